"""Shared by the tests of the scripts in benchmarks/ (they are files, not modules of the package)."""

import importlib.util
from pathlib import Path


def load_benchmark(name: str):
    """The module of benchmarks/<name>.py, loaded from its file."""
    path = Path(__file__).parents[2] / "benchmarks" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
