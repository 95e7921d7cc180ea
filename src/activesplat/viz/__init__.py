"""Figures and viewer."""
