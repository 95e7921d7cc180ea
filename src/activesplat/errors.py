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
