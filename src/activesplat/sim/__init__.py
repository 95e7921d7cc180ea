"""Simulated robot: scenes (procedural houses, mesh loading), Embree RGB-D sensor, agent and actions."""
