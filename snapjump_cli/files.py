"""Output files: where a write may go, and the one atomic write every output goes through.

Policy for an output path (the same for every command and every file it writes):

* a **regular file** (or no file yet) is written atomically: a temporary file in the same folder,
  flushed to disk, then renamed onto the path, with the mode the umask gives (0666 & ~umask);
* a **symbolic link** is followed: the file it points to is replaced atomically in *its* folder
  and the link stays a link, so a file shared through links stays shared (a dangling link creates
  its target);
* a **directory, FIFO, socket or device** is never replaced (:class:`OutputError`, even with
  ``--overwrite``), and nothing is ever written under ``/dev``, ``/proc`` or ``/sys``.

A failed write (a full disk, an I/O error) leaves the old file as it was and no temporary file
behind; it raises :class:`OutputError`, one line naming the path.
"""
from __future__ import annotations

import errno as errno_mod
import os
import shutil
import stat
import tempfile
from pathlib import Path
from typing import Any, Callable

__all__ = ["OutputError", "SYSTEM_FOLDERS", "current_umask", "follow_links", "output_target", "check_writable", "write_atomic",
           "AtomicFiles",
           "describe_os_error", "os_error_reason"]

#: Folders nothing is ever written under (device nodes, kernel interfaces).
SYSTEM_FOLDERS: tuple[str, ...] = ("/dev", "/proc", "/sys")


class OutputError(OSError):
    """An output that must not or could not be written; the message is one line naming the path.

    ``errno`` is that of the underlying failure (e.g. ``ENOSPC``), or ``None`` for a refused path.
    """

    def __init__(self, message: str, errno: int | None = None, reason: str | None = None) -> None:
        super().__init__(message)
        self.errno = errno
        self.reason = reason  # of a failed write: why, in words

    def __str__(self) -> str:
        return str(self.args[0])


def current_umask() -> int:
    """The process umask (read without changing it for longer than two system calls)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "directory"
    if stat.S_ISFIFO(mode):
        return "FIFO (named pipe)"
    if stat.S_ISCHR(mode):
        return "character device"
    if stat.S_ISBLK(mode):
        return "block device"
    if stat.S_ISSOCK(mode):
        return "socket"
    return "special file"


def _shown(path: Path, target: Path) -> str:
    return f"{path} (a link to {target})" if target != Path(os.path.abspath(path)) else str(path)


def output_target(path: str | os.PathLike, stat_fn: Callable[[Path], os.stat_result] = os.stat) -> Path:
    """The file that writing ``path`` replaces: ``path`` itself, or the end of its symbolic links.

    Parameters
    ----------
    path
        The output path as the user gave it.
    stat_fn
        How the target is examined (``os.stat``; tests pass a fake to present a device).

    Returns
    -------
    Path
        The absolute path of the regular file (existing or not) to write.

    Raises
    ------
    OutputError
        The target is a directory, FIFO, socket or device, lies under a system folder
        (:data:`SYSTEM_FOLDERS`), or the links form a loop.
    """
    path = Path(path)
    target = Path(os.path.realpath(path))
    shown = _shown(path, target)
    for d in SYSTEM_FOLDERS:
        if target == Path(d) or Path(d) in target.parents:
            raise OutputError(f"{shown}: refusing to write under {d} (a system folder)")
    try:
        if os.path.islink(target):  # realpath stopped on a link: a loop
            raise OutputError(f"{path}: symbolic link loop")
        st = stat_fn(target)
    except (FileNotFoundError, NotADirectoryError):  # not there yet (its folder is checked by the writer)
        return target
    except OutputError:
        raise
    except OSError as e:
        raise OutputError(f"{shown}: cannot examine it ({e.strerror})", e.errno) from None
    if stat.S_ISREG(st.st_mode):
        return target
    kind = _kind(st.st_mode)
    if kind == "directory":
        raise OutputError(f"{shown}: is a directory, expected a file path")
    raise OutputError(f"{shown}: is a {kind}, not a regular file; refusing to replace it")


def follow_links(path: str | os.PathLike) -> Path:
    """``path``, or the file its symbolic links end at (absolute) if it is a link."""
    path = Path(path)
    return Path(os.path.realpath(path)) if path.is_symlink() else path


def check_writable(path: str | os.PathLike, error: type[Exception] = OSError, what: str = "",
                   overwrite: bool = True) -> Path:
    """Make sure a file can be created at ``path``, without writing anything.

    The target (:func:`output_target`: links followed; never a directory, FIFO, socket, device or
    system folder) must be a regular file or absent, ``overwrite=False`` refuses an existing one,
    and its folder, or the nearest existing folder above it (the writer creates the rest), must be
    a writable folder. ``what="folder"`` checks a folder to write files into instead.

    Raises
    ------
    error
        One line naming the path (an ancestor that is a regular file, a read-only folder, an
        existing file without ``--overwrite``, a FIFO, ...).
    """
    path = Path(path)
    if what == "folder":
        folder = Path(os.path.realpath(path))
        for d in SYSTEM_FOLDERS:
            if folder == Path(d) or Path(d) in folder.parents:
                raise error(f"{path}: refusing to write under {d} (a system folder)")
        if folder.exists() and not folder.is_dir():
            raise error(f"{path}: is a file, expected a folder")
    else:
        try:
            target = output_target(path)
        except OutputError as e:
            raise error(str(e)) from None
        if not overwrite and target.exists():
            raise error(f"{path}: exists; pass --overwrite to replace it")
        folder = target.parent
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
    return path


def _fsync_file(p: str | os.PathLike) -> None:
    fd = os.open(p, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_folder(p: str | os.PathLike) -> None:
    """Best effort: some file systems cannot open or sync a folder (the rename is done anyway)."""
    try:
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def os_error_reason(e: BaseException) -> str:
    """Why an OS error happened, in words (``no space left on the device``, ``Permission denied``)."""
    if isinstance(e, OutputError) and e.reason:
        return e.reason
    text = str(e)
    if getattr(e, "errno", None) == errno_mod.ENOSPC or "No space left" in text:
        return "no space left on the device"
    return getattr(e, "strerror", None) or (text.splitlines()[0] if text else type(e).__name__)


def describe_os_error(e: OSError, path: str | os.PathLike | None = None) -> str:
    """One line for an OS error: ``<path>: <reason>`` (the path of the error if it names one,
    else ``path``)."""
    if isinstance(e, OutputError):
        return str(e)
    where = e.filename if e.filename is not None else path
    return f"{where}: {os_error_reason(e)}" if where is not None else os_error_reason(e)


class AtomicFiles:
    """Several outputs written all or none (``with AtomicFiles() as out: out.add(...); ...``).

    :meth:`add` writes each output into a new temporary file in its target's folder
    (:func:`output_target`: links followed; mode from the umask) and flushes it to disk; leaving the
    block normally renames every one onto its target, leaving it with an exception removes them
    all, so a failed command (a plot that cannot be drawn, a full disk) replaces none of its
    outputs. :meth:`file` and :meth:`folder` hand out a temporary file or folder for the caller to
    fill (a folder of files replaces its target whole). See :func:`write_atomic` for one file.
    """

    def __init__(self, stat_fn: Callable[[Path], os.stat_result] = os.stat) -> None:
        self._stat_fn = stat_fn
        self._pending: list[tuple[Path, Path, str]] = []  # (temporary file or folder, target, shown name)

    def _fail(self, shown: str, e: OSError, note: str = "") -> OutputError:
        why = os_error_reason(e)
        return OutputError(f"{shown}: cannot write it ({why}){note}", e.errno, why)

    def file(self, path: str | os.PathLike) -> Path:
        """A new, empty temporary file (mode from the umask) that replaces ``path`` when the block
        ends without an error; the caller writes it.

        Raises
        ------
        OutputError
            ``path`` may not be written (see the module docstring), or its folder cannot take a file.
        """
        path = Path(path)
        target = output_target(path, self._stat_fn)
        shown = _shown(path, target)
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=f".{target.stem}.", suffix=f".tmp{target.suffix}", dir=target.parent)
        except OSError as e:
            raise self._fail(shown, e) from None
        self._pending.append((Path(tmp), target, shown))
        try:
            os.fchmod(fd, 0o666 & ~current_umask())
        except OSError as e:
            raise self._fail(shown, e) from None
        finally:
            os.close(fd)
        return Path(tmp)

    def folder(self, path: str | os.PathLike) -> Path:
        """A new, empty temporary folder (mode from the umask) that replaces the folder ``path``
        whole when the block ends without an error; the caller fills it (its files' modes are the
        caller's).

        Raises
        ------
        OutputError
            ``path`` is something other than a folder (a file, a FIFO, ...) or lies under a system
            folder, or its parent cannot take a folder.
        """
        path = Path(path)
        target = Path(os.path.realpath(path))
        shown = _shown(path, target)
        for d in SYSTEM_FOLDERS:
            if target == Path(d) or Path(d) in target.parents:
                raise OutputError(f"{shown}: refusing to write under {d} (a system folder)")
        if target.exists() and not target.is_dir():
            raise OutputError(f"{shown}: is not a folder; refusing to replace it")
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            tmp = tempfile.mkdtemp(prefix=f".{target.name}.", dir=target.parent)
            os.chmod(tmp, 0o777 & ~current_umask())
        except OSError as e:
            raise self._fail(shown, e) from None
        self._pending.insert(0, (Path(tmp), target, shown))  # folders first: a file naming one comes after
        return Path(tmp)

    def add(self, path: str | os.PathLike, write: Callable[[Path], Any]) -> Path:
        """Write ``path``'s new content with ``write(tmp)`` into a temporary file (:meth:`file`),
        flushed to disk; it replaces ``path`` when the block ends without an error. Returns ``path``.

        Raises
        ------
        OutputError
            The path may not be written (see the module docstring), or the write failed (full
            disk, I/O error): one line naming the path, ``errno`` set.
        """
        path = Path(path)
        tmp = self.file(path)
        try:
            write(tmp)
            _fsync_file(tmp)
        except OSError as e:
            if isinstance(e, OutputError) and e.reason is None:  # a refused path
                raise
            # (also a write nested in ``write``: named here by its target)
            raise self._fail(self._pending[-1][2], e, "; the previous file, if any, is unchanged") from None
        return path

    def discard(self) -> None:
        """Remove every temporary file and folder made so far (no target is touched)."""
        for tmp, _, _ in self._pending:
            if tmp.is_dir() and not tmp.is_symlink():
                shutil.rmtree(tmp, ignore_errors=True)
            else:
                try:
                    os.unlink(tmp)
                except OSError:
                    pass
        self._pending = []

    def commit(self) -> list[Path]:
        """Flush every temporary file to disk and rename it onto its target (done by leaving the
        block normally). Returns the targets."""
        done, folders = [], []
        try:
            for tmp, _, shown in self._pending:  # everything on disk before the first rename
                if not tmp.is_dir():
                    try:
                        _fsync_file(tmp)
                    except OSError as e:
                        raise self._fail(shown, e) from None
            while self._pending:
                tmp, target, shown = self._pending[0]
                try:
                    if tmp.is_dir() and target.is_dir():
                        shutil.rmtree(target)
                    os.replace(tmp, target)
                except OSError as e:
                    raise self._fail(shown, e) from None
                self._pending.pop(0)
                done.append(target)
                folders.append(target.parent)
        finally:
            self.discard()
        for folder in dict.fromkeys(folders):
            _fsync_folder(folder)
        return done

    def __enter__(self) -> "AtomicFiles":
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        if exc_type is None:
            self.commit()
        else:
            self.discard()


def write_atomic(path: str | os.PathLike, write: Callable[[Path], Any], stat_fn: Callable[[Path], os.stat_result]
                 = os.stat) -> Path:
    """Replace the file at ``path`` atomically with what ``write(tmp)`` writes into ``tmp``.

    ``tmp`` is a new file in the target's folder (:func:`output_target`: links followed), made
    with the mode the umask gives; once ``write`` returns it is flushed to disk and renamed onto
    the target, so a reader sees the old file or the new one, never a part. If ``write`` (or the
    flush) fails, the old file is untouched and ``tmp`` removed. Missing folders are created.

    Returns
    -------
    Path
        ``path`` as given.

    Raises
    ------
    OutputError
        The path may not be written (see the module docstring), or the write failed (full disk,
        I/O error): one line naming the path, ``errno`` set.
    """
    with AtomicFiles(stat_fn) as out:
        out.add(path, write)
    return Path(path)
