"""Offline refinement of the map from the keyframe buffer (paper sec. III-D4)."""
