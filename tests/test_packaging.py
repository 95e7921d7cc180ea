"""What a user gets without a checkout: `pip install activesplat` (a wheel) or the sdist.

The wheel must hold every module and every file the package reads at run time; the package must read no file
of the checkout (docs/, benchmarks/, ...), which a wheel install does not have; the sdist must hold the whole
test suite, the docs, the benchmark scripts and constraints.txt. The build test runs the build backend itself,
as `python -m build` does: the sdist first, then the wheel from the unpacked sdist."""

import ast
import fnmatch
import shutil
import subprocess
import sys
import tarfile
import tomllib
import zipfile
from pathlib import Path

import pytest

import activesplat

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "activesplat"
CACHES = ("__pycache__", ".pytest_cache", ".ruff_cache")
CACHE_FILES = ("*.pyc", "*.pyo", "*.nbi", "*.nbc")


def _files(folder: Path) -> list[Path]:
    """The files under `folder`, without Python's and numba's caches."""
    return sorted(p for p in folder.rglob("*") if p.is_file() and not set(p.parts) & set(CACHES)
                  and not any(fnmatch.fnmatch(p.name, pat) for pat in CACHE_FILES))


def _package_data() -> dict[str, list[str]]:
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    return pyproject.get("tool", {}).get("setuptools", {}).get("package-data", {})


def _declared(path: Path, package_data: dict[str, list[str]]) -> bool:
    """Whether a file under src/activesplat matches a [tool.setuptools.package-data] pattern of its package
    (or of "*", any package)."""
    rel = path.relative_to(PACKAGE.parent)
    for package, patterns in package_data.items():
        base = PACKAGE.parent if package == "*" else PACKAGE.parent.joinpath(*package.split("."))
        if package != "*" and base not in path.parents:
            continue
        inner = path.relative_to(base).as_posix() if package != "*" else rel.name
        if any(fnmatch.fnmatch(inner, pattern) for pattern in patterns):
            return True
    return False


def test_every_file_the_package_ships_besides_modules_is_declared_package_data():
    """A texture, shader, weight or json file under src/activesplat reaches a wheel only when pyproject.toml
    declares it (an editable install reads it from the checkout and hides the omission)."""
    data = [p for p in _files(PACKAGE) if p.suffix != ".py"]
    package_data = _package_data()
    undeclared = [str(p.relative_to(ROOT)) for p in data if not _declared(p, package_data)]
    assert not undeclared, f"add to [tool.setuptools.package-data] in pyproject.toml: {undeclared}"


def test_the_package_locates_no_file_by_its_own_path():
    """Paths built from __file__ work in a checkout and break in a wheel as soon as they leave the package
    (../../docs, ../../benchmarks). Data inside the package is read with importlib.resources instead."""
    found = []
    for path in _files(PACKAGE):
        if path.suffix != ".py":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Name) and node.id == "__file__":
                found.append(f"{path.relative_to(ROOT)}:{node.lineno}")
    assert not found, f"read package files with importlib.resources.files('activesplat...'): {found}"


def test_the_package_data_helper_sees_an_undeclared_file(tmp_path):
    """The check above can fail: a file outside every pattern is undeclared, one inside is declared."""
    texture = PACKAGE / "sim" / "textures" / "wood.png"
    assert not _declared(texture, {})
    assert not _declared(texture, {"activesplat.sim": ["*.json"]})
    assert _declared(texture, {"activesplat.sim": ["textures/*.png"]})
    assert _declared(texture, {"*": ["*.png"]})
    assert not _declared(texture, {"activesplat.splat": ["textures/*.png"]})


def _build(tmp_path: Path) -> tuple[Path, Path]:
    """(sdist, wheel) built as `python -m build` builds them, from a copy of the source tree."""
    pytest.importorskip("setuptools", minversion="77")  # the dev extra installs it
    tree = tmp_path / "tree"
    ignore = shutil.ignore_patterns(*CACHES, *CACHE_FILES, "*.egg-info", "runs", "build", "dist", ".venv")
    tree.mkdir()
    for name in ("pyproject.toml", "MANIFEST.in", "README.md", "LICENSE", "constraints.txt",
                 "constraints-oldest.txt"):
        shutil.copy2(ROOT / name, tree / name)
    for name in ("src", "tests", "docs", "benchmarks"):
        shutil.copytree(ROOT / name, tree / name, ignore=ignore)
    out = tmp_path / "dist"
    out.mkdir()

    def backend(hook: str, cwd: Path) -> Path:
        code = f"import setuptools.build_meta as b; print(b.{hook}({str(out)!r}))"
        done = subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True, text=True,
                              timeout=300)
        assert done.returncode == 0, done.stderr[-3000:]
        return out / done.stdout.strip().splitlines()[-1]

    sdist = backend("build_sdist", tree)
    with tarfile.open(sdist) as tar:
        tar.extractall(tmp_path / "unpacked", filter="data")
    wheel = backend("build_wheel", tmp_path / "unpacked" / sdist.name.removesuffix(".tar.gz"))
    return sdist, wheel


@pytest.fixture(scope="module")
def dists(tmp_path_factory):
    return _build(tmp_path_factory.mktemp("build"))


def test_the_wheel_holds_every_module_and_data_file_and_its_metadata(dists):
    _, wheel = dists
    version = activesplat.__version__
    with zipfile.ZipFile(wheel) as zf:
        names = set(zf.namelist())
        info = f"activesplat-{version}.dist-info"
        metadata = zf.read(f"{info}/METADATA").decode()
        entry_points = zf.read(f"{info}/entry_points.txt").decode()
    want = {p.relative_to(PACKAGE.parent).as_posix() for p in _files(PACKAGE)}
    assert not want - names, f"missing from the wheel: {sorted(want - names)}"
    assert not {n for n in names if n.startswith(("tests/", "docs/", "benchmarks/"))}
    assert f"{info}/licenses/LICENSE" in names
    header = metadata.split("\n\n", 1)[0].splitlines()
    assert f"Version: {version}" in header and "License-Expression: MIT" in header
    assert "Requires-Python: >=3.11" in header
    assert any(line.startswith("Classifier: ") for line in header)
    assert "activesplat = activesplat.cli:main" in entry_points


def test_the_sdist_holds_the_tests_docs_benchmarks_and_pinned_versions(dists):
    sdist, _ = dists
    with tarfile.open(sdist) as tar:
        top = sdist.name.removesuffix(".tar.gz")
        names = {n.removeprefix(top + "/") for n in tar.getnames()}
    want = {p.relative_to(ROOT).as_posix() for folder in (PACKAGE, ROOT / "tests", ROOT / "docs",
                                                          ROOT / "benchmarks") for p in _files(folder)}
    want |= {"pyproject.toml", "README.md", "LICENSE", "constraints.txt", "constraints-oldest.txt"}
    assert not want - names, f"missing from the sdist: {sorted(want - names)}"
    assert not [n for n in names if "__pycache__" in n or n.endswith((".pyc", ".nbi", ".nbc"))]


def _pins(path: Path) -> dict[str, str]:
    """name -> version of a constraints file's ``name==version`` lines (names lower-case)."""
    lines = (line.split("#")[0].strip() for line in path.read_text().splitlines())
    return {name.strip().lower(): version.strip() for name, version in
            (line.split("==") for line in lines if line)}


def _release(version: str) -> tuple[int, ...]:
    """The leading numbers of a version ("2.17.7.post6" -> (2, 17, 7))."""
    parts = []
    for part in version.split("."):
        if not part.isdigit():
            break
        parts.append(int(part))
    return tuple(parts)


def test_constraints_oldest_holds_every_lower_bound_of_pyproject():
    """constraints-oldest.txt installs the lowest version of every ``>=`` range of pyproject.toml (the
    dependencies and the dev extra), the versions the suite was last run with at the bottom of those ranges:
    a bound raised or added without it fails here."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    bounds = {}
    for requirement in [*project["dependencies"], *project["optional-dependencies"]["dev"]]:
        if ">=" in requirement:
            name, rest = requirement.split(">=")
            bounds[name.strip().lower()] = rest.split(",")[0].strip()
    oldest = _pins(ROOT / "constraints-oldest.txt")
    assert set(bounds) == set(oldest), (sorted(set(bounds) - set(oldest)), sorted(set(oldest) - set(bounds)))
    for name, bound in bounds.items():
        low = _release(bound)
        assert _release(oldest[name])[:len(low)] == low, (name, bound, oldest[name])
