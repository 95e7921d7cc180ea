"""Exceptions for bad input. The command line turns these into a one-line error and exit code 2."""


class ActiveSplatError(Exception):
    """Base class of every error caused by bad input (files, names, values), not by a bug."""


class SceneError(ActiveSplatError, ValueError):
    """A scene cannot be loaded or used: unknown built-in name, unreadable or corrupt mesh,
    no walkable floor."""


class SceneNotFoundError(SceneError, FileNotFoundError):
    """A scene file that does not exist."""


class InvalidActionError(ActiveSplatError, ValueError):
    """An action name the simulator does not know."""


class InvalidInputError(ActiveSplatError, ValueError):
    """Any other bad argument: shapes, NaN/inf values, out-of-range numbers."""


class EpisodeError(ActiveSplatError, ValueError):
    """A folder that is not a (complete) episode, or one that would be overwritten."""


class RecordingError(InvalidInputError):
    """A recording that cannot be mapped: the message names the topic (or file) and the message."""


class Interrupted(KeyboardInterrupt):
    """Ctrl-C, after the command has said on stderr what it stopped and what it left behind (its one line):
    the command line exits with 130 without a line of its own."""


def check_fields(obj, *, positive: tuple[str, ...] = (), non_negative: tuple[str, ...] = (),
                 unit: tuple[str, ...] = (), at_least_one: tuple[str, ...] = (),
                 optional: tuple[str, ...] = ()) -> None:
    """Validate the named numeric fields of a config dataclass: ``positive`` > 0, ``non_negative`` >= 0,
    ``unit`` in [0, 1], ``at_least_one`` >= 1; a field also named in ``optional`` may be None (off). The
    first one out of range raises an InvalidInputError naming it as ``ClassName.field``."""
    rules = [(positive, lambda v: v > 0, "> 0"), (non_negative, lambda v: v >= 0, ">= 0"),
             (unit, lambda v: 0 <= v <= 1, "in [0, 1]"), (at_least_one, lambda v: v >= 1, ">= 1")]
    for names, ok, text in rules:
        for name in names:
            value = getattr(obj, name)
            if value is None and name in optional:
                continue
            if not ok(value):
                off = " (or None = off)" if name in optional else ""
                raise InvalidInputError(f"{type(obj).__name__}.{name} must be {text}{off}, got {value}")


_BAD_PATH = (FileExistsError, FileNotFoundError, NotADirectoryError, IsADirectoryError, PermissionError)


def cannot_write(path, exc: OSError, label: str = "") -> Exception:
    """The one-line InvalidInputError of an output path that cannot be written (a file where a folder should
    be, a folder in the file's place, a missing or read-only location), ``label`` (e.g. an option name)
    before the path; any other OSError (a full disk) is returned as it is, for the command line's own
    message."""
    if not isinstance(exc, _BAD_PATH):
        return exc
    where = f"{label} {path}: cannot write it" if label else f"cannot write {path}"
    blocked = blocked_path(path)
    if blocked:
        return InvalidInputError(f"{where}{', ' if label else ': '}{blocked}")
    return InvalidInputError(f"{where} ({exc.strerror or type(exc).__name__})")


def blocked_path(path) -> str:
    """Why no file can be written at `path`, before trying: "it is a folder", or "X is a file, not a folder"
    for the nearest existing folder above it that is a file; "" when nothing stands in the way."""
    from pathlib import Path

    path = Path(path)
    if path.is_dir():
        return "it is a folder"
    for parent in path.parents:
        if parent.exists():
            return "" if parent.is_dir() else f"{parent} is a file, not a folder"
    return ""
