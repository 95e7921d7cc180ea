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
