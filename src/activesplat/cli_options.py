"""The run configuration's dataclasses as command-line options, through tyro.

``explore``, ``refine`` and ``benchmark`` (and the benchmarks' own scripts) parse their options with
:func:`parse_command`: every field of :mod:`activesplat.config` is an option ``--GROUP.FIELD VALUE``, the
fields derived from others are left out, every help text is one clean paragraph, and a parse failure is a
:class:`CommandLineError` with one line that names the option (with "did you mean" for a typo).
"""

from __future__ import annotations

import dataclasses
import functools
import re
from collections.abc import Sequence

from activesplat.errors import ActiveSplatError


class CommandLineError(ActiveSplatError):
    """Bad options of a tyro-parsed command (unknown option, wrong type, value out of range)."""


def _config_path(argv: Sequence[str]) -> str | None:
    """The value of --config, read before the other options, whose defaults it gives."""
    for i, token in enumerate(argv):
        if token == "--config" and i + 1 < len(argv):
            return argv[i + 1]
        if token.startswith("--config="):
            return token.split("=", 1)[1]
    return None


def help_text(text: str | None) -> str | None:
    """A docstring as one help paragraph: tyro keeps a docstring's line breaks before a line that starts with
    anything but a letter (``(3.0)``, ``and``, after its indentation), which split sentences mid-line; and it
    wraps a long word at a comma, which splits a number such as 30,000. Paragraphs (blank lines) stay."""
    if not text:
        return text
    # a section comment above a field ("# --- schedule ...") is its help when it has no docstring: no dashes
    paragraphs = [re.sub(r"^-{3,}\s*", "", " ".join(p.split())) for p in re.split(r"\n\s*\n", text)]
    return "\n\n".join(re.sub(r"(?<=\d),(?=\d{3}(?!\d))", "", p) for p in paragraphs if p)


def _field_help(helptext, struct_type=None) -> str | None:
    """help_text of a (possibly lazy) tyro field help; for a nested group without its own docstring, of the
    group's class docstring (tyro's fallback, evaluated here so that it is cleaned too)."""
    from tyro import _docstrings

    text = helptext() if callable(helptext) else helptext
    if text is None and struct_type is not None:
        text = _docstrings.get_callable_description(struct_type)
    return help_text(text)


def _default_hint(helptext, label: str) -> str:
    """tyro's "(default: X)" after a field's help, left out when the help says its default itself (a None
    that means "runs/SCENE-POLICY-sSEED" would read "(default: None)" twice)."""
    return "" if "(default" in (_field_help(helptext) or "") else f"(default: {label})"


def _registry(hidden: dict):
    """tyro constructors that leave out the fields derived from others (and those a command sets itself), and
    that clean every field's help (`help_text`)."""
    from typing import Literal

    import tyro
    from tyro.constructors import ConstructorRegistry
    from tyro.constructors._struct_spec_dataclass import dataclass_rule

    from activesplat.config import PolicyName, strip_annotated
    from activesplat.planning.policies import policy_names

    registry = ConstructorRegistry()

    def field(f, names):
        if f.type is PolicyName:  # the policies of this run: the built-in ones and those added since import
            f = dataclasses.replace(f, type=Literal[policy_names()])
        if f.name in names:
            return dataclasses.replace(f, type=tyro.conf.Suppress[f.type])
        nested = strip_annotated(f.type)
        nested = nested if dataclasses.is_dataclass(nested) else None
        f = dataclasses.replace(f, helptext=functools.partial(_field_help, f.helptext, nested))
        if f.default is None:
            hint = tyro.conf.arg(help_behavior_hint=functools.partial(_default_hint, f.helptext))
            f = dataclasses.replace(f, type=_annotated(f.type, hint))
        return f

    @registry.struct_rule
    def rule(info):
        spec = dataclass_rule(info)
        if spec is None:
            return None
        names = hidden.get(info.type, ())
        return dataclasses.replace(spec, fields=tuple(field(f, names) for f in spec.fields))

    return registry


def _annotated(tp, *metadata):
    """``Annotated[tp, *metadata]`` (a helper: the subscript takes a tuple)."""
    from typing import Annotated

    return Annotated[(tp, *metadata)]


def _hidden_fields(own: Sequence[str] = ()) -> dict:
    """{dataclass: field names} not offered as options: the derived ones, and `own` fields of RunConfig."""
    from activesplat.config import DERIVED, RunConfig

    hidden: dict = {RunConfig: set(own)} if own else {}
    for path in DERIVED:
        *groups, name = path.split(".")
        holder = RunConfig()
        for group in groups:
            holder = getattr(holder, group)
        hidden.setdefault(type(holder), set()).add(name)
    return hidden


def _options(cls, hidden: dict) -> list[str]:
    """Every option of a command dataclass, for "did you mean"."""
    from activesplat.config import RunConfig, option_paths

    own = hidden.get(RunConfig, set())
    flags = []
    for name, tp in command_fields(cls).items():
        if name == "run":  # flattened: its fields are top-level options
            flags += [p for p in option_paths() if p not in own]
        elif dataclasses.is_dataclass(tp):
            flags += list(option_paths(tp, name + "."))
        else:
            flags.append(name)
    return ["--" + f.replace("_", "-") for f in flags]


def command_fields(cls) -> dict:
    """{field name: type} of a command dataclass (Annotated stripped)."""
    import typing

    from activesplat.config import strip_annotated

    hints = typing.get_type_hints(cls)
    return {f.name: strip_annotated(hints[f.name]) for f in dataclasses.fields(cls)}


def _removed(flag: str) -> str | None:
    """When and why the field of option `flag` (``--explorer.global-tour``, or a boolean's
    ``--explorer.no-global-tour``) was removed from RunConfig (`config.REMOVED`); None for any other."""
    from activesplat.config import REMOVED

    group, _, name = flag[2:].replace("-", "_").rpartition(".")
    for leaf in (name, name.removeprefix("no_")):
        entry = REMOVED.get(f"{group}.{leaf}" if group else leaf)
        if entry is not None:
            return entry[1]
    return None


def _parse_error(event, options: list[str]) -> str:
    """One line for a tyro parse failure, naming the option."""
    import difflib

    from tyro import _errors

    from activesplat.config import DERIVED, name_fields

    def flag(arg) -> str:
        return "/".join(arg.lowered.name_or_flags) if arg is not None else "?"

    if isinstance(event, _errors.UnrecognizedArgs):
        token = event.tokens[0]
        if not token.startswith("-"):
            return f"unexpected argument {token!r}"
        name = token.split("=", 1)[0]
        source = DERIVED.get(name[2:].replace("-", "_"))
        if source is not None:
            return f"{name} is derived from the robot's settings: set --sim.{source.replace('_', '-')}"
        removed = _removed(name)
        if removed is not None:
            return f"{name} was removed ({removed})"
        near = difflib.get_close_matches(name, options, n=1)
        return f"unknown option {name}" + (f" (did you mean {near[0]}?)" if near else "")
    if isinstance(event, _errors.InvalidChoice):
        name, choices = flag(event.argument), ", ".join(event.choices)
        if "." in name:
            return f"{name}: unknown value {event.value!r}; choose one of: {choices}"
        return f"unknown {name.lstrip('-')} {event.value!r}; choose one of: {choices}"
    if isinstance(event, _errors.BadValue):
        if event.offending_value is not None:
            return f"{flag(event.argument)}: cannot take {event.offending_value!r}"
        nargs = getattr(event.argument.lowered, "nargs", None)
        return f"{flag(event.argument)}: expects {nargs if isinstance(nargs, int) else 'a'} value(s)"
    if isinstance(event, _errors.InstantiationFailure):
        message = name_fields(event.message, flags=True).strip().split("\n")[0]  # tyro adds detail lines
        if event.argument is None:
            return message
        metavar = event.argument.lowered.metavar
        return f"{flag(event.argument)} expects {metavar}: {message}"
    if isinstance(event, _errors.MissingArgs):
        names = [a.arg.lowered.metavar if a.arg.is_positional() else flag(a.arg)
                 for a in event.missing_arguments]
        return f"missing {', '.join(str(n) for n in names)}"
    return f"bad options ({type(event).__name__})"


def parse_command(cls, argv: Sequence[str], prog: str, own: Sequence[str] = (), default=None):
    """`argv` as a command dataclass (ExploreCommand, BenchmarkCommand, RefineCommand), its defaults from
    `default` or, for a command with a `run`, from --config. Bad input raises CommandLineError with one
    line naming the option; --help prints and exits."""
    import tyro
    from tyro import _errors

    from activesplat.config import load_run_config, name_fields

    if default is None and "run" in command_fields(cls):
        path = _config_path(argv)
        default = cls(run=load_run_config(path)) if path is not None else cls()
    hidden = _hidden_fields(own)

    def fail(event) -> None:  # the options for "did you mean": listed only here (half a parse's time)
        raise CommandLineError(_parse_error(event, _options(cls, hidden)))

    try:
        with _errors.on_parse_error(fail):
            return tyro.cli(cls, args=list(argv), prog=prog, registry=_registry(hidden),
                            **({} if default is None else {"default": default}))
    except CommandLineError:
        raise
    except ActiveSplatError as exc:  # a check of the outermost dataclass, outside tyro's own handling
        raise CommandLineError(name_fields(str(exc), flags=True)) from None
