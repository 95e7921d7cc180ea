"""Simulated robot: scenes (procedural houses, mesh loading), Embree RGB-D sensor, agent and actions.

```python
from activesplat.sim import load_scene, Simulator
scene = load_scene("small-0")
sim = Simulator(scene, seed=0)
obs = sim.reset()
obs = sim.step("move_forward")
```
"""

from activesplat.geometry import camera_pose, intrinsics
from activesplat.sim.config import SimConfig
from activesplat.sim.house import HouseConfig
from activesplat.sim.navmap import NavMap
from activesplat.sim.scene import Scene, box_room, describe_builtin_scenes, load_scene
from activesplat.sim.sensor import RGBDSensor
from activesplat.sim.simulator import ACTIONS, AgentState, Observation, Simulator

__all__ = [
    "ACTIONS",
    "AgentState",
    "HouseConfig",
    "NavMap",
    "Observation",
    "RGBDSensor",
    "Scene",
    "SimConfig",
    "Simulator",
    "box_room",
    "camera_pose",
    "describe_builtin_scenes",
    "intrinsics",
    "load_scene",
]
