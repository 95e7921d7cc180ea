"""Multi-room behaviour of finished episodes: rooms entered, per-room coverage against the sweep ceiling,
rotation share, steps to 90 / 95 % of the ceiling, Tab. III (completion at fractions of the path length).

    python benchmarks/rooms.py runs/medium-0-activesplat-s0 [more episode folders] [--ceilings DIR]

Episodes written before coverage.npz existed are replayed from poses.txt (a minute or two per 2000 steps).
The sweep ceiling of each scene is cached in DIR/<scene>.json (default runs/ceilings; a medium house takes
about 8 minutes on 2 cores the first time). Writes trajectory.png into each episode folder.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from activesplat.episode import read_episode
from activesplat.eval.behaviour import (
    BehaviourConfig,
    at_path_fractions,
    episode_behaviour,
    relative_to_ceiling,
)
from activesplat.eval.coverage import CoverageConfig
from activesplat.eval.replay import replay_coverage
from activesplat.eval.sweep import sweep_ceiling
from activesplat.sim import SimConfig, load_scene
from activesplat.viz.trajectory import draw_trajectory, room_labels


def completed_mask(episode, scene, cfg: CoverageConfig, sim_config: SimConfig) -> np.ndarray:
    """The episode's coverage.npz, else the mask from replaying its actions (checked against poses.txt)."""
    path = episode.dir / "coverage.npz"
    if path.is_file():
        data = np.load(path)
        return np.unpackbits(data["completed"])[: int(data["n"])].astype(bool)
    return replay_coverage(scene, episode.start_pose, episode.actions, cfg, expected_poses=episode.poses,
                           sim_config=sim_config, with_completed=True)["completed"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("episodes", nargs="+", type=Path)
    ap.add_argument("--ceilings", type=Path, default=Path("runs/ceilings"))
    args = ap.parse_args()
    bcfg = BehaviourConfig()
    rows = []
    for folder in args.episodes:
        episode = read_episode(folder)
        metrics = json.loads((folder / "metrics.json").read_text())
        scene = load_scene(episode.meta["scene"])
        cfg, sim_config = CoverageConfig(), SimConfig()
        completed = completed_mask(episode, scene, cfg, sim_config)
        gt = scene.sample_surface(cfg.n_gt_points, seed=cfg.seed)
        xz = episode.poses[:, [0, 2], 3]
        found = episode_behaviour(episode.actions, xz, scene.house, gt, completed, bcfg)
        metrics.update(found)
        ceiling = sweep_ceiling(scene, args.ceilings / f"{scene.name}.json", sim_config, progress=True)
        rel = relative_to_ceiling(metrics, ceiling, bcfg)
        tab3 = at_path_fractions(metrics.get("curve", []), bcfg.path_fractions)
        labels = {}
        if scene.house is not None:
            labels = room_labels(scene.house, found["rooms"], rel.get("room_of_ceiling_pct", {}),
                                 unit="% of ceiling")
        draw_trajectory(folder / "trajectory.png", scene.navmap_for(sim_config), xz, scene.house, labels,
                        title=f"{folder.name}: trajectory over the floor plan")
        rows.append((folder, metrics, rel, tab3))
        print(f"\n## {folder}  ({scene.name}, {metrics.get('policy')}, seed {metrics.get('seed')})")
        print(f"completion {metrics['completion_ratio_pct']:.2f} % | ceiling {rel['ceiling_pct']:.2f} % | "
              f"of ceiling {rel['of_ceiling_pct']:.1f} % | rotations {found['rotation_pct']:.1f} % "
              f"{found['action_counts']}")
        if scene.house is not None:
            print(f"rooms entered {found['rooms_entered']}/{found['rooms_total']}: "
                  f"{found['rooms']['entered']}")
            print("room share of its ceiling: " + ", ".join(
                f"{k} {v:.0f}" for k, v in rel.get("room_of_ceiling_pct", {}).items()))
        print("steps to 90 / 95 % of ceiling: "
              f"{rel.get('steps_to_90_pct_ceiling')} / {rel.get('steps_to_95_pct_ceiling')}")
        print("Tab. III (path %: completion %): " + ", ".join(
            f"{100 * r['fraction']:.0f}: {r['completion_ratio_pct']:.2f}" for r in tab3))
    print("\n| episode | completion % | of ceiling % | worst room % | rooms entered | rotations % | "
          "steps to 90 % | steps to 95 % |")
    print("|---|---|---|---|---|---|---|---|")
    for folder, m, rel, _ in rows:
        worst = rel.get("worst_room_of_ceiling_pct")
        print(f"| {folder.name} | {m['completion_ratio_pct']:.2f} | {rel['of_ceiling_pct']:.1f} | "
              f"{'n/a' if worst is None else f'{worst:.1f}'} | {m.get('rooms_entered', 'n/a')}/"
              f"{m.get('rooms_total', 'n/a')} | {m['rotation_pct']:.1f} | "
              f"{rel.get('steps_to_90_pct_ceiling')} | {rel.get('steps_to_95_pct_ceiling')} |")


if __name__ == "__main__":
    main()
