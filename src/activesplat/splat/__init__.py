"""Gaussian map: parameters, rasterizer backends, online mapper (paper sec. III-A)."""
