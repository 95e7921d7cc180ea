"""Workspace and topology (paper sec. III-A, III-C): top-down maps, Voronoi graph, subregions, safe paths."""
