"""Viewpoint selection and hierarchical planning (paper sec. III-B, III-C)."""
