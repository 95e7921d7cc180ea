"""The package's dependency order: sim -> splat -> workspace -> planning -> eval / refine -> viz ->
config / explore / bench / cli. A module imports only from its own layer or the layers before it (eval never
from refine), at module level and inside functions alike."""

import ast
from pathlib import Path

import activesplat

ROOT = Path(activesplat.__file__).parent
BASE = ("errors", "geometry", "timing", "episode", "env", "config_history")
"""Top-level helpers every layer may use (config_history: the fields added and removed since, which
evaluation reads to rebuild an old episode's simulator)."""
LAYERS = [BASE, ("sim",), ("splat",), ("workspace",), ("planning",), ("eval", "refine"), ("viz",),
          ("config", "explore", "explore_setup", "live_completion", "explore_summary",
           "bench", "cli", "cli_options", "__main__", "robot")]


def _layer(name: str) -> int:
    for i, names in enumerate(LAYERS):
        if name in names:
            return i
    raise AssertionError(f"activesplat.{name} belongs to no layer: add it to LAYERS")


def _imports(path: Path) -> set[str]:
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("activesplat."):
            out.add(node.module.split(".")[1])
        elif isinstance(node, ast.Import):
            out |= {a.name.split(".")[1] for a in node.names if a.name.startswith("activesplat.")}
    return out


def test_every_module_imports_only_from_its_layer_or_before():
    wrong = []
    for path in sorted(ROOT.rglob("*.py")):
        rel = path.relative_to(ROOT)
        me = rel.parts[0] if len(rel.parts) > 1 else rel.stem
        if me == "__init__":
            continue
        for other in _imports(path) - {me}:
            if _layer(other) > _layer(me) or (me, other) == ("eval", "refine"):
                wrong.append(f"{rel} imports activesplat.{other}")
    assert not wrong, "\n".join(wrong)
