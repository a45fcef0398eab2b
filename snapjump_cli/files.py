"""Generic file helpers of the commands and the library: the check that an output can be written
(:func:`check_writable`, before any work), the atomic creation of a file (:func:`replace_atomic`:
a temporary file in the same folder, then a rename, with the mode the umask gives) and the
process umask."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Any, Callable

__all__ = ["check_writable", "current_umask", "replace_atomic"]


def check_writable(path: str | Path, error: type[Exception] = OSError, what: str = "",
                   overwrite: bool = True) -> Path:
    """Make sure a file can be created at ``path``, without writing anything: its folder, or the
    nearest existing folder above it (the writer creates the rest), is a writable folder, and
    (``overwrite=False``) no file is there already. Raises ``error`` with one line naming the path
    otherwise (an ancestor that is a regular file, a read-only folder, an existing file without
    ``--overwrite``, ...)."""
    path = Path(path)
    if not overwrite and what != "folder" and path.is_file():
        raise error(f"{path}: exists; pass --overwrite to replace it")
    folder = path if what == "folder" else path.parent
    anc = folder
    while not anc.exists() and anc != anc.parent:
        anc = anc.parent
    if anc.exists() and not anc.is_dir():
        raise error(f"{path}: cannot write here, {anc} is a file, not a folder")
    try:  # a real probe: permission bits say nothing to root, nor about read-only file systems
        fd, probe = tempfile.mkstemp(prefix=".snapjump-probe-", dir=anc)
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        raise error(f"{path}: the folder {anc} is not writable ({e.strerror})") from None
    if what != "folder" and path.is_dir():
        raise error(f"{path}: is a directory, expected a file path")
    return path


def current_umask() -> int:
    """The process umask (read without changing it for longer than two system calls)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def replace_atomic(write: Callable[[Path], Any], path: str | Path) -> Path:
    """Create ``path`` atomically: ``write(tmp)`` writes a temporary file in the same folder, which
    then replaces ``path`` (mode from the umask). Nothing is left behind if ``write`` fails."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=f".tmp{path.suffix}", dir=path.parent)
    os.close(fd)
    try:
        os.chmod(tmp, 0o666 & ~current_umask())
        write(Path(tmp))
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    return path
