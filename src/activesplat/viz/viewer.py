"""Web viewers built on viser: `activesplat explore --viewer` (live) and `activesplat view DIR` (replay).

Both serve a page on localhost showing the Gaussian map as splats, the agent's camera frustum and
trajectory, the Voronoi graph with its nodes coloured by subregion (and the eq. 12 scores of the last
replan as bars), the current goal and path, the top-down workspace grid, and the latest RGB-D images and
panorama. The world frame is used as is: y up (`set_up_direction("+y")`), cameras in OpenCV axes, which is
also viser's frustum convention, so no conversion is needed anywhere.

This module gathers the viewers' public names; they live in:

- `activesplat.viz.live`: `LiveViewer`, the page of a running exploration (rate-limited updates);
- `activesplat.viz.replay`: `EpisodeViewer`, the page of a finished episode, a recorded map or a refined
  one (timeline slider, map menu), and `view_from_args` (`activesplat view`);
- `activesplat.viz.server`: what both share: `ViewerConfig` and the server of the page (`start_server`);
- `activesplat.viz.drawing`: what both draw (`SceneDrawer`) and the images and splat arrays it sends.
"""

from activesplat.viz.drawing import SceneDrawer, depth_image, panorama_image, splat_arrays
from activesplat.viz.live import LiveViewer
from activesplat.viz.replay import ONLINE, EpisodeViewer, map_files, view_folder, view_from_args
from activesplat.viz.server import ViewerConfig, free_port, start_server

__all__ = ["ONLINE", "EpisodeViewer", "LiveViewer", "SceneDrawer", "ViewerConfig", "depth_image", "free_port",
           "map_files", "panorama_image", "splat_arrays", "start_server", "view_from_args", "view_folder"]
