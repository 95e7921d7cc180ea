"""Evaluation: completion metrics by replay, rendering metrics, timing (paper sec. IV)."""
