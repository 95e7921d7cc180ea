"""Exceptions for bad input, and the checks of output paths. The command line turns these into a one-line
error and exit code 2."""

import contextlib
import contextvars
import errno


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


_QUIET_INTERRUPTS = contextvars.ContextVar("quiet_interrupts", default=False)


def interrupted(line: str) -> Interrupted:
    """The `Interrupted` of a Ctrl-C, `line` (what was stopped, what is kept, how to resume) printed on
    stderr on a line of its own (after a progress bar's); inside :func:`quiet_interrupts` it is not
    printed."""
    import sys

    if not _QUIET_INTERRUPTS.get():
        print(f"\n{line}", file=sys.stderr)
    return Interrupted(line)


@contextlib.contextmanager
def quiet_interrupts():
    """Within it, the commands' own work (an exploration) does not print its Ctrl-C line: for a caller that
    says in its own line what was kept (a benchmark, whose partial runs are explored again)."""
    token = _QUIET_INTERRUPTS.set(True)
    try:
        yield
    finally:
        _QUIET_INTERRUPTS.reset(token)


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


# --------------------------------------------------------------------------- output paths
# Every command that writes a file or folder the user names checks it with check_output_file /
# check_output_folder before any slow work (scene build, mapping, training), and turns an OSError of the
# write itself into the same one-line message with cannot_write.

def check_output_file(path, label: str = "") -> None:
    """Refuse, in one line (InvalidInputError), an output file that cannot be written: a folder stands in
    its place, a file stands where a folder above it should be, or the folder it would be written in (or
    the nearest existing folder above it: missing folders are made) is not writable. ``label`` (e.g. an
    option name, ``--mcap``) is put before the path. Nothing is created."""
    from pathlib import Path

    path = Path(path)
    where = f"cannot write {label} {path}" if label else f"cannot write {path}"
    if path.is_dir():
        raise InvalidInputError(f"{where}: it is a folder")
    _check_above(path, where)


def check_output_folder(path, label: str = "") -> None:
    """Refuse, in one line (InvalidInputError), an output folder that cannot be written into: a file
    stands in its place or where a folder above it should be, or it (or, when it does not exist yet, the
    nearest existing folder above it, where it would be made) is not writable. ``label`` as in
    :func:`check_output_file`. Nothing is created."""
    from pathlib import Path

    path = Path(path)
    where = f"cannot write into {label} {path}" if label else f"cannot write into {path}"
    if path.exists() and not path.is_dir():
        raise InvalidInputError(f"{where}: it is a file, not a folder")
    if path.is_dir():
        _check_writable(path, where, "it")
    else:
        _check_above(path, where)


def cannot_write(path, exc: OSError, label: str = "") -> Exception:
    """The one-line InvalidInputError of an output file whose writing failed with `exc` (a file where a
    folder should be, a folder in the file's place, a missing or read-only location), worded as
    :func:`check_output_file` words it; any other OSError (a full disk) is returned as it is, for the
    command line's own message."""
    if not isinstance(exc, _BAD_PATH):
        return exc
    from pathlib import Path

    where = f"cannot write {label} {path}" if label else f"cannot write {path}"
    if Path(path).is_dir():
        return InvalidInputError(f"{where}: it is a folder")
    blocker = _file_above(Path(path))
    if blocker is not None:
        return InvalidInputError(f"{where}: {blocker} is a file, not a folder")
    return InvalidInputError(f"{where} ({exc.strerror or type(exc).__name__})")


_BAD_PATH = (FileExistsError, FileNotFoundError, NotADirectoryError, IsADirectoryError, PermissionError)
_FULL = (errno.ENOSPC, errno.EDQUOT)


def _file_above(path):
    """The nearest existing path above `path` when it is a file (no folder can be made under it), else
    None."""
    for parent in path.parents:
        if parent.exists():
            return None if parent.is_dir() else parent
    return None


def _check_above(path, where: str) -> None:
    """`path` does not exist (or is a file to replace): the nearest existing folder above it must be a
    folder, and writable."""
    for parent in path.parents:
        if parent.exists():
            if not parent.is_dir():
                raise InvalidInputError(f"{where}: {parent} is a file, not a folder")
            _check_writable(parent, where, str(parent))
            return


def _check_writable(folder, where: str, name: str) -> None:
    """A file can be made in `folder` (tried with an unnamed temporary file, which leaves nothing behind):
    an InvalidInputError when not (a read-only folder or file system, a folder such as /proc), except for a
    full disk, raised as it is for the command line's own message."""
    import tempfile

    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        if exc.errno in _FULL:
            raise
        raise InvalidInputError(f"{where}: {name} is not writable ({exc.strerror})") from None
