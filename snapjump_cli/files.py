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
behind; it raises :class:`OutputError`, one line naming the path. So does a stop by SIGTERM (or
Ctrl-C) while temporary files are pending: SIGTERM is turned into an interruption for as long as
any are, so they are removed before the process ends (only SIGKILL can leave one behind).

Outputs are locked: ``<output>.lock`` (:class:`OutputLock`, taken by every command that writes a
result for as long as it runs) names the process (pid, host, the process's start time); every
write refuses a target whose lock another running process holds. A lock whose process is gone, or
whose pid now belongs to another process (the start time differs), is taken over.

Working folders (a sweep's ``<output>.parts/``): the tool removes only the files it wrote there
(regular files with its own names), never follows a symbolic link inside them, and refuses a
working folder that is itself a link (:func:`own_folder`, :func:`own_files`, :func:`remove_own`).
Inputs are read only from regular files (:func:`check_readable`: never a FIFO or a device, which
could block for ever).
"""
from __future__ import annotations

import errno as errno_mod
import json
import logging
import os
import re
import shutil
import signal
import socket
import stat
import tempfile
import threading
from contextlib import contextmanager
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Callable, Iterator

log = logging.getLogger(__name__)

__all__ = ["OutputError", "SYSTEM_FOLDERS", "current_umask", "follow_links", "output_target", "check_writable", "write_atomic",
           "AtomicFiles", "check_readable", "own_folder", "own_files", "remove_own", "remove_own_folder",
           "OutputLock", "LockTaken", "lock_path", "process_start", "foreign_lock",
           "describe_os_error", "os_error_reason", "remedy"]

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


def remedy(e: BaseException) -> str:
    """What to do about a failed write, in words: ``free some space`` only when the disk is full."""
    if getattr(e, "errno", None) in (errno_mod.ENOSPC, errno_mod.EDQUOT) or "No space left" in str(e):
        return "free some space"
    if getattr(e, "errno", None) in (errno_mod.EACCES, errno_mod.EPERM, errno_mod.EROFS):
        return "make the place writable (or choose another output)"
    return "move what is in the way"


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
        self._restore: Any = None  # the SIGTERM handler to put back once nothing is pending

    def _guard(self) -> None:
        """While temporary files are pending, SIGTERM interrupts (KeyboardInterrupt) instead of
        ending the process on the spot, so that :meth:`discard` removes them (main thread only)."""
        if self._restore is not None or threading.current_thread() is not threading.main_thread():
            return
        try:
            current = signal.getsignal(signal.SIGTERM)
        except (ValueError, OSError):  # pragma: no cover - no signals here
            return
        if current is signal.SIG_DFL:
            self._restore = signal.signal(signal.SIGTERM, _terminate_as_interrupt)

    def _unguard(self) -> None:
        if self._restore is not None:
            try:
                signal.signal(signal.SIGTERM, self._restore)
            finally:
                self._restore = None

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
        holder = foreign_lock(target)
        if holder:
            raise OutputError(f"{shown}: {holder} is writing this file; wait for it to finish (or remove "
                              f"{lock_path(target)} if that process is gone)")
        self._guard()
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
        self._guard()
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
        self._unguard()

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


def _terminate_as_interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt


# ---- inputs -------------------------------------------------------------------------------------
def check_readable(path: str | os.PathLike, error: type[Exception] = OSError, what: str = "a file") -> Path:
    """Make sure ``path`` is a regular file to read (links followed), before it is opened.

    A FIFO, a socket or a device would block the reader or never end, a directory cannot be read.

    Raises
    ------
    error
        One line naming the path and what it is instead.
    """
    path = Path(path)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise error(f"{path}: file not found") from None
    except OSError as e:
        raise error(f"{path}: cannot read it ({e.strerror})") from None
    if stat.S_ISREG(st.st_mode):
        return path
    raise error(f"{path}: expected {what}, got a {_kind(st.st_mode)}")


# ---- working folders: the tool removes only what it wrote, never through a link -----------------
def own_folder(path: str | os.PathLike, error: type[Exception] = OutputError) -> Path:
    """Create, or accept, a working folder of the tool (``<output>.parts``): a real folder.

    Raises
    ------
    error
        ``path`` is a symbolic link (the tool never works through a link inside its own places),
        a file, or cannot be created.
    """
    path = Path(path)
    for _ in range(2):
        try:
            st = os.lstat(path)
        except FileNotFoundError:
            try:
                path.mkdir(parents=True, exist_ok=True)
            except OSError as e:
                raise error(f"{path}: cannot create the folder ({os_error_reason(e)})") from None
            continue
        if stat.S_ISLNK(st.st_mode):
            raise error(f"{path}: is a symbolic link, not a folder snapjump made; it never works through links "
                        f"in its own folders: remove the link (its target is not touched) and run again")
        if not stat.S_ISDIR(st.st_mode):
            raise error(f"{path}: is a {_kind(st.st_mode) if not stat.S_ISREG(st.st_mode) else 'file'}, "
                        f"expected snapjump's working folder: move it away")
        return path
    raise error(f"{path}: cannot create the folder")


def _is_real_folder(path: Path) -> bool:
    try:
        return stat.S_ISDIR(os.lstat(path).st_mode)
    except OSError:
        return False


def own_files(folder: str | os.PathLike, pattern: str | re.Pattern[str], warn: bool = True) -> list[Path]:
    """The regular files in ``folder`` whose names match ``pattern`` (a regular expression that
    must match the whole name), in name order: what the tool may have written there.

    A symbolic link, a folder or a special file with such a name is not the tool's: it is left
    out (and left in place), with a warning (``warn``). Nothing is listed in a folder that is
    itself a link or not there.
    """
    folder = Path(folder)
    if not _is_real_folder(folder):
        return []
    rx = re.compile(pattern) if isinstance(pattern, str) else pattern
    out = []
    try:
        names = sorted(os.listdir(folder))
    except OSError:
        return []
    for name in names:
        if not rx.fullmatch(name):
            continue
        p = folder / name
        try:
            st = os.lstat(p)
        except OSError:
            continue
        if stat.S_ISREG(st.st_mode):
            out.append(p)
        elif warn:
            kind = "symbolic link" if stat.S_ISLNK(st.st_mode) else _kind(st.st_mode)
            log.warning("%s: a %s snapjump did not write; ignored and left in place", p, kind)
    return out


def remove_own(path: str | os.PathLike) -> bool:
    """Remove ``path`` if it is a regular file (never a link, a folder or a special file; a link
    is never followed). Returns whether it was removed."""
    path = Path(path)
    try:
        if not stat.S_ISREG(os.lstat(path).st_mode):
            log.warning("%s: not a file snapjump wrote; left in place", path)
            return False
        os.unlink(path)
        return True
    except FileNotFoundError:
        return False
    except OSError as e:
        log.debug("could not remove %s: %s", path, e)
        return False


def remove_own_folder(folder: str | os.PathLike, pattern: str | re.Pattern[str] | None = None) -> bool:
    """Remove the tool's own files in ``folder`` (:func:`own_files` with ``pattern``; ``None``:
    none), then the folder if it is empty. A folder that is a link is never entered nor removed.
    Returns whether the folder is gone."""
    folder = Path(folder)
    if not _is_real_folder(folder):
        return not os.path.lexists(folder)
    if pattern is not None:
        for p in own_files(folder, pattern):
            remove_own(p)
    try:
        folder.rmdir()
        return True
    except OSError:  # not empty (something not ours, or new): left for later
        return False


# ---- locks --------------------------------------------------------------------------------------
def lock_path(output: str | os.PathLike) -> Path:
    """The lock file of ``output``: ``<output>.lock``."""
    output = Path(output)
    return output.with_name(output.name + ".lock")


def _boot_id() -> str | None:
    try:
        return Path("/proc/sys/kernel/random/boot_id").read_text().strip() or None
    except OSError:
        return None


def process_start(pid: int) -> int | None:
    """When process ``pid`` started (clock ticks since boot, from ``/proc``), or ``None`` if it does
    not run or this system does not say. A pid reused by a later process has another start."""
    try:
        raw = Path(f"/proc/{int(pid)}/stat").read_bytes()
    except (OSError, ValueError):
        return None
    try:  # the command name (field 2) may hold spaces and parentheses: split after its last ')'
        return int(raw[raw.rindex(b")") + 2:].split()[19])
    except (ValueError, IndexError):
        return None


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # it exists, owned by someone else
        return True
    except OSError:
        return False
    return True


#: Locks held by this process (their paths), so that its own writes pass them.
_HELD: set[str] = set()


def _read_lock(path: Path) -> dict[str, Any]:
    """The holder recorded in a lock file (``{}`` if it is not a small regular file of JSON)."""
    try:
        st = os.lstat(path)
        if not stat.S_ISREG(st.st_mode) or st.st_size > 65536:
            return {"unreadable": True}
        h = json.loads(path.read_text())
        return h if isinstance(h, dict) else {"unreadable": True}
    except FileNotFoundError:
        return {}
    except (OSError, ValueError):
        return {"unreadable": True}


def _stale(h: dict[str, Any]) -> str:
    """Why the holder of a lock is gone (``""``: it may still run, or it cannot be told from here)."""
    pid, host = h.get("pid"), h.get("host")
    if host != socket.gethostname() or not isinstance(pid, int) or isinstance(pid, bool):
        return ""
    if h.get("boot_id") and _boot_id() and h["boot_id"] != _boot_id():
        return "the machine has restarted since"
    if not _pid_alive(pid):
        return "no longer runs"
    started = h.get("proc_start")
    if isinstance(started, int) and process_start(pid) not in (None, started):
        return "its pid now belongs to another process"
    return ""


def _describe_holder(h: dict[str, Any]) -> tuple[str, str]:
    """(``another sweep``, ``pid 12 on host, started ...``) of a lock's holder."""
    if not h or h.get("unreadable"):
        return "another process", "an unreadable lock file"
    return (f"another {h.get('command', 'snapjump')}",
            f"pid {h.get('pid')} on {h.get('host')}, started {h.get('started_utc')}")


def foreign_lock(target: str | os.PathLike) -> str:
    """Who else holds the lock of ``target`` (``""``: nobody, a holder that is gone, or this process)."""
    p = lock_path(target)
    if os.path.realpath(p) in _HELD or not os.path.lexists(p):
        return ""
    h = _read_lock(p)
    if not h or _stale(h):
        return ""
    who, detail = _describe_holder(h)
    return f"{who} ({detail})"


class LockTaken(OutputError):
    """The output is being written by another process (one line naming it)."""


class OutputLock:
    """Exclusive right to write one output (``<output>.lock``, created with ``O_EXCL``), taken by
    every command that writes a result (``command`` is recorded in the lock and named to whoever
    finds it taken).

    The lock records the pid, the host, the process's start time (:func:`process_start`) and the
    boot. A second writer is refused (``error``, default :class:`LockTaken`, naming the holder). A
    lock left by a process that no longer runs on this host, or whose pid now belongs to another
    process, is taken over with a warning. A lock from another host is never broken automatically
    (its process cannot be checked from here): the message says which file to remove.
    """

    def __init__(self, output: str | os.PathLike, command: str = "sweep", error: type[Exception] = LockTaken) -> None:
        self.path = lock_path(output)
        self.command = command
        self.error = error
        self.held = False

    def acquire(self) -> "OutputLock":
        me = {"pid": os.getpid(), "host": socket.gethostname(),
              "started_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"), "command": self.command,
              "proc_start": process_start(os.getpid()), "boot_id": _boot_id()}
        for _ in range(3):
            try:
                fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o666)
            except FileExistsError:
                h = _read_lock(self.path)
                why = _stale(h) if h and not h.get("unreadable") else ""
                if why:
                    log.warning("%s: taking over a stale lock (pid %s on %s, started %s: %s)",
                                self.path, h.get("pid"), h.get("host"), h.get("started_utc"), why)
                    remove_own(self.path)
                    continue
                if not h:  # removed meanwhile
                    continue
                who, detail = _describe_holder(h)
                raise self.error(
                    f"{self.path.with_suffix('')}: {who} is writing into this output ({detail}); "
                    f"wait for it to finish, or remove {self.path} if that process is gone")
            except OSError as e:
                raise self.error(f"{self.path}: cannot create the lock file ({os_error_reason(e)})") from None
            try:
                with os.fdopen(fd, "w") as fh:
                    json.dump(me, fh)
            except OSError as e:  # a full disk: leave no empty lock behind (it would block every rerun)
                self.path.unlink(missing_ok=True)
                raise self.error(f"{self.path}: cannot write the lock file ({os_error_reason(e)})") from None
            self.held = True
            _HELD.add(os.path.realpath(self.path))
            return self
        raise self.error(f"{self.path}: cannot take the lock")

    def release(self) -> None:
        if self.held:
            _HELD.discard(os.path.realpath(self.path))
            self.path.unlink(missing_ok=True)
            self.held = False

    def __enter__(self) -> "OutputLock":
        return self.acquire()

    def __exit__(self, *exc: Any) -> None:
        self.release()
