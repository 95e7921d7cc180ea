"""README.md's command lines stay true: every ``activesplat ...`` line of its code blocks and inline code is
parsed by the real parser of that subcommand (tyro for explore / benchmark / refine, argparse for the
others), every ``python benchmarks/SCRIPT.py ...`` line by that script's own argparse parser, and every option
the README names on its own (``--mapper.edge-band-px 2``, ``refine --no-lpips``) is one that a subcommand
knows. Nothing is run: the parsers only parse.

The README's placeholders are read as the commands' users would fill them in: ``DIR``, ``FILE``, ``N``, ...
get a plausible value (`PLACEHOLDERS`), ``[...]`` marks optional parts, ``a|b`` alternatives (each one is
parsed), ``...`` more of the same, and ``--GROUP.FIELD VALUE`` stands for any run-configuration option.
docs/*.md are not checked: their tuning logs keep the commands of their time on purpose."""

import argparse
import contextlib
import functools
import importlib.util
import io
import json
import re
import sys
import warnings
from pathlib import Path
from unittest import mock

import pytest

from activesplat.cli import TYRO_COMMANDS, build_parser
from activesplat.cli_options import _hidden_fields, _registry, parse_command
from activesplat.config import BENCHMARK_OWN, BenchmarkCommand, ExploreCommand, RefineCommand, RunConfig
from activesplat.errors import ActiveSplatError

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"

TYRO = {"explore": (ExploreCommand, ()), "benchmark": (BenchmarkCommand, BENCHMARK_OWN),
        "refine": (RefineCommand, ())}
assert set(TYRO) == set(TYRO_COMMANDS)

PLACEHOLDERS = {
    "DIR": "runs/x", "FILE": "runs/x.out", "EPISODE": "runs/x", "E": "runs/x", "E2000": "runs/x",
    "E4000": "runs/y", "ROOT": "runs/benchmark", "BASE": "runs/a", "NEW": "runs/b", "NAME": "small-0",
    "RECORDING": "walk.mcap", "N": "2", "S": "0", "PX": "512", "HEIGHT": "3.0", "P": "activesplat",
    "T": "/topic", "TOPIC": "/odom", "FX": "200", "FY": "200", "CX": "128", "CY": "128",
}
"""A value for each placeholder word the README's commands use (a word in capitals standing for a whole
argument). A new placeholder fails the test until it is added here."""
BY_OPTION = {"--scenes": "small-0", "--policies": "activesplat", "--policy": "activesplat"}
"""The value of a placeholder (``--policy NAME``) or of ``...`` (``--scenes ...``) after these options."""
FOREIGN = {"--no-deps": "pip's", "--sh_degree": "the original 3DGS loader's",
           "--budget-min": "benchmarks/render.py's"}
"""Options the README names that belong to other programs (none of activesplat's subcommands)."""
SUBCOMMAND = re.compile(r"^(explore|benchmark|refine|evaluate|render-eval|view|compare|scenes|map|robot"
                        r"|export)\b")


# --------------------------------------------------------------------------- finding the command lines
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)


def code_snippets(text: str) -> list[tuple[int, str]]:
    """(line number, text) of every command-like piece of `text`, in line order: each ``&&`` / ``;`` part
    of a line of a fenced block other than ``python`` (``\\`` continuation lines joined), and each inline
    code span (one that runs over a line break joined, ``\\|`` of a table cell read as ``|``)."""
    found = []
    for m in FENCE.finditer(text):
        if m.group(1) == "python":  # the Python API block: tests/test_readme_api.py runs it
            continue
        first = text.count("\n", 0, m.start(2)) + 1
        pending, start = "", None
        for i, line in enumerate(m.group(2).split("\n")):
            start = first + i if start is None else start
            if line.rstrip().endswith("\\"):
                pending += line.rstrip()[:-1] + " "
                continue
            for part in re.split(r"&&|;", pending + line):
                if part.strip():
                    found.append((start, " ".join(part.split())))
            pending, start = "", None
    outside = FENCE.sub(lambda m: "\n" * m.group(0).count("\n"), text)  # same line numbers, no blocks
    for m in re.finditer(r"`([^`]+)`", outside):
        if "\n\n" not in m.group(1):
            line = outside.count("\n", 0, m.start()) + 1
            found.append((line, " ".join(m.group(1).replace("\\|", "|").split())))
    return sorted(found, key=lambda f: f[0])


# --------------------------------------------------------------------------- the parsers
@functools.cache
def _argparse_subcommands() -> dict[str, argparse.ArgumentParser]:
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return {name: p for name, p in sub.choices.items() if name not in TYRO}


@functools.cache
def _tyro_parser(command: str) -> argparse.ArgumentParser:
    """The argparse parser that tyro.cli builds for `command`."""
    import tyro.extras

    cls, own = TYRO[command]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # get_parser: still there in the pinned tyro
        return tyro.extras.get_parser(cls, registry=_registry(_hidden_fields(own)))


@functools.cache
def option_names(command: str) -> frozenset[str]:
    """Every option string the parser of `command` knows (``scenes``: of its actions too)."""
    parser = _tyro_parser(command) if command in TYRO else _argparse_subcommands()[command]
    names = set(parser._option_string_actions)
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for p in action.choices.values():
                names |= set(p._option_string_actions)
    return frozenset(names)


def _argparse_error(parser: argparse.ArgumentParser, argv: list[str]) -> str | None:
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            parser.parse_args(argv)
        except SystemExit as exc:
            if exc.code:
                return err.getvalue().strip().splitlines()[-1].split("error: ", 1)[-1]
    return None


class _Parsed(Exception):
    pass


@functools.cache
def _bench_module(script: str):
    path = ROOT / "benchmarks" / f"{script}.py"
    spec = importlib.util.spec_from_file_location(f"_readme_benchmarks_{script}", path)
    module = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(path.parent))
    try:
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(path.parent))
    return module


def _bench_error(script: str, argv: list[str]) -> str | None:
    """`argv` parsed by benchmarks/SCRIPT.py's parser: its main() stopped where it parses."""
    if not (ROOT / "benchmarks" / f"{script}.py").is_file():
        return f"no such script benchmarks/{script}.py"
    module = _bench_module(script)
    parse = argparse.ArgumentParser.parse_args

    def parse_only(self, args=None, namespace=None):
        raise _Parsed(parse(self, argv, namespace))

    err = io.StringIO()
    with mock.patch.object(argparse.ArgumentParser, "parse_args", parse_only), \
            contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            module.main()
        except _Parsed:
            return None
        except SystemExit as exc:
            if exc.code:
                return err.getvalue().strip().splitlines()[-1].split("error: ", 1)[-1]
    return f"benchmarks/{script}.py: main() did not parse its arguments (cannot be checked)"


# --------------------------------------------------------------------------- the checker
def _is_template(option: str) -> bool:
    """``--GROUP.FIELD``, ``--refine.FIELD``: any option of that kind."""
    return any(c.isupper() for c in option)


def _value(token: str, option: str | None, config_file: str) -> str:
    if option == "--config":
        return config_file
    if re.fullmatch(r"[A-Z][A-Z0-9_]*", token):
        if option in BY_OPTION:
            return BY_OPTION[option]
        if token not in PLACEHOLDERS:
            raise KeyError(f"placeholder {token} is not in PLACEHOLDERS (tests/test_readme_commands.py)")
        return PLACEHOLDERS[token]
    return token


def argv_variants(tokens: list[str], config_file: str) -> list[list[str]]:
    """The README's argument words as argument lists: brackets dropped, placeholders filled in, templates
    and ``...`` left out; one list with the first of every ``a|b`` and one for each other alternative."""
    argv: list[list[str]] = []  # the alternatives of each argument
    option = None
    words = [t.strip("[]") for t in tokens]
    words = [w for w in words if w]
    i = 0
    while i < len(words):
        word = words[i]
        if word.startswith("--") and _is_template(word):
            i += 2 if i + 1 < len(words) and words[i + 1].isupper() else 1
            continue
        if word == "...":
            if option in BY_OPTION and argv and argv[-1] == [option]:
                argv.append([BY_OPTION[option]])
            i += 1
            continue
        if word.startswith("-"):
            option = word.split("=", 1)[0]
            argv.append([word])
        else:
            argv.append([_value(w, option, config_file) for w in word.split("|")])
        i += 1
    base = [alternatives[0] for alternatives in argv]
    variants = [base]
    for k, alternatives in enumerate(argv):
        variants += [base[:k] + [other] + base[k + 1:] for other in alternatives[1:]]
    return variants


def parse_error(command: str, argv: list[str]) -> str | None:
    """What the parser of `command` says against `argv` (None: parsed)."""
    if command in TYRO:
        cls, own = TYRO[command]
        try:
            with contextlib.redirect_stdout(io.StringIO()):  # `explore --help` prints and exits 0
                parse_command(cls, argv, f"activesplat {command}", own=own)
        except ActiveSplatError as exc:
            return str(exc)
        except SystemExit as exc:
            return f"exit code {exc.code}" if exc.code else None
        return None
    return _argparse_error(_argparse_subcommands()[command], argv)


def _unknown_options(words: list[str], known: frozenset[str]) -> list[str]:
    options = [w.strip("[]").split("=", 1)[0] for w in words if w.strip("[").startswith("--")]
    return [f"unknown option {o}" for o in options
            if not _is_template(o) and o not in known and o not in FOREIGN]


def check(text: str, config_file: str) -> list[str]:
    """Problems of one README snippet (empty: it is true, or it is not a command)."""
    words = text.split()
    try:
        if text.startswith("activesplat "):
            command = words[1]
            if command not in TYRO and command not in _argparse_subcommands():
                return [f"unknown subcommand {command!r}"]
            if len(words) == 2:  # the subcommand named in a sentence
                return []
            variants = argv_variants(words[2:], config_file)
            return list(dict.fromkeys(p for argv in variants if (p := parse_error(command, argv))))
        if m := re.match(r"python3? benchmarks/(\w+)\.py\b", text):
            return list(dict.fromkeys(p for argv in argv_variants(words[2:], config_file)
                                      if (p := _bench_error(m.group(1), argv))))
        if m := re.match(r"bash (benchmarks/[\w.-]+\.sh)\b", text):
            return [] if (ROOT / m.group(1)).is_file() else [f"no such script {m.group(1)}"]
    except KeyError as exc:
        return [exc.args[0]]
    if (m := SUBCOMMAND.match(text)) and " --" in text:  # `refine --no-lpips`: names only
        return _unknown_options(words[1:], option_names(m.group(1)))
    if text.startswith("--"):
        every = frozenset().union(*(option_names(c) for c in (*TYRO, *_argparse_subcommands())))
        problems = _unknown_options(words, every)
        if problems:
            return problems
        return _dotted_values(words, config_file)
    return []


def _dotted_values(words: list[str], config_file: str) -> list[str]:
    """The run-configuration options of a snippet (``--mapper.edge-band-px 2``) parsed by `explore` with
    their values, where every one is such an option and has its value or is a flag (else only their names
    are checked)."""
    groups: list[list[str]] = []
    for word in words:
        if word.startswith("--"):
            if "." not in word or _is_template(word):
                return []
            groups.append([word])
        else:
            groups[-1].append(_value(word, groups[-1][0], config_file))
    flags = _tyro_parser("explore")._option_string_actions
    if not groups or any(len(g) == 1 and flags[g[0]].nargs != 0 for g in groups):
        return []
    problem = parse_error("explore", [w for g in groups for w in g])
    return [problem] if problem else []


# --------------------------------------------------------------------------- tests
@pytest.fixture
def config_file(tmp_path) -> str:
    """A run configuration for ``--config EPISODE/episode.json``."""
    path = tmp_path / "episode.json"
    path.write_text(json.dumps(RunConfig().to_dict()))
    return str(path)


def test_readme_commands_parse(config_file):
    snippets = code_snippets(README.read_text())
    commands = [s for s in snippets if s[1].startswith(("activesplat ", "python benchmarks/"))]
    assert len(commands) > 40, f"found only {len(commands)} command lines in README.md: the search broke"
    found = {text: check(text, config_file) for text in dict.fromkeys(text for _, text in snippets)}
    problems = [f"README.md line {line}: `{text[:90]}{'...' if len(text) > 90 else ''}`: {problem}"
                for line, text in snippets for problem in found[text]]
    assert not problems, "\n" + "\n".join(problems)


@pytest.mark.parametrize("text, needle", [
    ("activesplat explore --scene small-0 --mapper.edge-band-pxx 2", "unknown option --mapper.edge-band-pxx"),
    ("activesplat explore [--steps N] [--backend auto|numba|torchh]", "torchh"),
    ("activesplat explore --steps many", "--steps"),
    ("activesplat refine DIR [--method 3dgs|2dgs] [--iter 2000]", "--iter"),
    ("activesplat benchmark [--scenes ...] [--trails N]", "--trails"),
    ("activesplat render-eval DIR [--n-trian 50]", "--n-trian"),
    ("activesplat export DIR --ply FILE [--sh-degree 0|4]", "4"),
    ("activesplat explor --scene small-0", "unknown subcommand 'explor'"),
    ("activesplat scenes exports NAME FILE", "exports"),
    ("activesplat view DIR --port P0RT", "P0RT"),
    ("activesplat view DIR --port PORT", "placeholder PORT"),
    ("python benchmarks/sweep.py --spacingg 1", "--spacingg"),
    ("python benchmarks/nothere.py", "no such script"),
    ("python benchmarks/render.py --iters 2000", "required: episode"),  # no default on one machine
    ("bash benchmarks/gpu_sped.sh", "no such script benchmarks/gpu_sped.sh"),
    ("--explorer.cut-off-look", "unknown option --explorer.cut-off-look"),
    ("--mapper.edge-band-px two", "--mapper.edge-band-px"),
    ("refine --no-lpipss", "unknown option --no-lpipss"),
])
def test_the_checker_finds_a_wrong_line(text, needle, config_file):
    problems = check(text, config_file)
    assert problems and needle in problems[0], problems


def test_the_checker_reads_the_readme_notation(config_file):
    words = "DIR [--method 3dgs|2dgs] [--GROUP.FIELD VALUE ...] --iters N".split()
    assert argv_variants(words, config_file) == [["runs/x", "--method", "3dgs", "--iters", "2"],
                                                 ["runs/x", "--method", "2dgs", "--iters", "2"]]
    assert argv_variants(["--scenes", "...", "--config", "EPISODE/episode.json"], config_file) \
        == [["--scenes", "small-0", "--config", config_file]]
    text = ("intro `activesplat view DIR`, a span `activesplat benchmark --scenes\nsmall-0` and\n"
            "| `x \\| y` |\n```bash\nactivesplat explore \\\n    --steps 5 && activesplat evaluate D\n```\n"
            "```python\nactivesplat = 1\n```\nlast `--z-up`\n")
    assert code_snippets(text) == [(1, "activesplat view DIR"), (1, "activesplat benchmark --scenes small-0"),
                                   (3, "x | y"), (5, "activesplat explore --steps 5"),
                                   (5, "activesplat evaluate D"), (11, "--z-up")]
