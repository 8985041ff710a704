"""Policy folders and files written so that they are never half done nor redirected.

A new policy folder (:class:`NewPolicyFolder`, :func:`write_policy_folder`) is checked before any
work (:func:`check_new_folder`), held by a lock for the whole command (a second writer is refused
with one line naming the first) and written once: into a staging folder beside it (the same
file system), every file flushed to disk, ``metadata.json`` with the sha256 of the others written
last and verified, then renamed into place. A kill leaves either no folder or the whole one (and
a staging folder that the next writer of that place removes: :func:`stale_temporaries`); nothing
is written through a symbolic link. A single file (:func:`write_file`) is written through a
temporary file beside it and an atomic rename."""
from __future__ import annotations

import contextlib
import datetime
import json
import os
import shutil
import socket
import stat
from collections.abc import Callable
from pathlib import Path
from types import TracebackType
from typing import Any

WriteFiles = Callable[[Path], dict[str, Any]]   # writes a folder's files, returns its metadata
_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)
_CLOEXEC = getattr(os, "O_CLOEXEC", 0)


def occupied(folder: str | Path) -> bool:
    """Whether ``folder`` exists as anything but an empty folder (a new policy folder's check);
    a symbolic link, dangling or not, counts as occupied."""
    path = Path(folder)
    if path.is_symlink():
        return True
    return path.exists() and (not path.is_dir() or any(path.iterdir()))


def _names_no_folder(folder: str | Path) -> bool:
    return not str(folder).strip() or Path(folder).name in ("", ".", "..")


def check_new_folder(folder: str | Path, option: str = "--out") -> None:
    """Refuse, before any work, a folder a new policy cannot be written to: an empty name (or
    ``.``/``..``), one that exists and is not an empty folder (a file, a folder with files), a
    symbolic link, or a place whose parent folder cannot be created or written (checked by
    writing and removing a probe file). ValueError naming ``option``."""
    if _names_no_folder(folder):
        raise ValueError(f"{option} {str(folder)!r} names no new folder; give one, e.g. "
                         "runs/policy")
    path = Path(folder)
    if occupied(path):
        what = ("is a symbolic link" if path.is_symlink() else
                "is a file" if not path.is_dir() else "exists and is not empty")
        raise ValueError(f"{option} {str(path)!r} {what}; give a new folder")
    parent = path.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
        probe = parent / f".{path.name}.probe-{os.getpid()}"
        fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW, 0o600)
        os.close(fd)
        probe.unlink()
    except OSError as exc:
        raise ValueError(f"{option} {str(path)!r} cannot be written: {str(parent)!r} "
                         f"({exc.strerror or exc})") from None


def check_file_target(path: str | Path, option: str) -> None:
    """Refuse, before any work, a file that cannot be (re)written: an empty name, a folder, a
    symbolic link or anything but a regular file, or a parent folder that cannot be created or
    written. ValueError naming ``option``."""
    if _names_no_folder(path):
        raise ValueError(f"{option} {str(path)!r} names no file; give one")
    p = Path(path)
    with contextlib.suppress(FileNotFoundError):
        mode = os.lstat(p).st_mode
        if not stat.S_ISREG(mode):
            what = ("a symbolic link" if stat.S_ISLNK(mode) else
                    "a folder" if stat.S_ISDIR(mode) else "not a regular file")
            raise ValueError(f"{option} {str(p)!r} is {what}; give a file name")
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        probe = p.parent / f".{p.name}.probe-{os.getpid()}"
        os.close(os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW, 0o600))
        probe.unlink()
    except OSError as exc:
        raise ValueError(f"{option} {str(p)!r} cannot be written: {str(p.parent)!r} "
                         f"({exc.strerror or exc})") from None


def refuse_links(folder: str | Path, option: str = "--out") -> None:
    """Refuse a folder that is, or holds at any depth, a symbolic link (a writer into it would
    write wherever the link points): ValueError naming ``option`` and the first link."""
    root = Path(folder)
    if root.is_symlink():
        raise ValueError(f"{option} {str(root)!r} is a symbolic link; give the folder itself")
    if not root.is_dir():
        return
    for here, dirs, files in os.walk(root, followlinks=False):
        for name in sorted(dirs + files):
            path = Path(here) / name
            if path.is_symlink():
                raise ValueError(f"{option} {str(root)!r} holds a symbolic link "
                                 f"{str(path.relative_to(root))!r}; files are written into it "
                                 "only as real files: remove the link")


def fsync_file(path: Path) -> None:
    """Flush a file's bytes to disk."""
    fd = os.open(path, os.O_RDONLY | _NOFOLLOW)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def fsync_dir(path: Path) -> None:
    """Flush a folder's entries to disk (where the platform can)."""
    with contextlib.suppress(OSError):
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def write_file(path: str | Path, data: bytes | str) -> Path:
    """Write ``data`` as the file ``path`` through a new temporary file beside it (never through
    a symbolic link: one at ``path`` is refused), flushed and renamed into place: a kill leaves
    the old file or the new one, never half of it."""
    p = Path(path)
    with contextlib.suppress(FileNotFoundError):
        if not stat.S_ISREG(os.lstat(p).st_mode):
            raise ValueError(f"{str(p)!r} is not a regular file (a symbolic link, a folder?); "
                             "it is not written through")
    tmp = p.parent / f".{p.name}.tmp-{os.getpid()}"
    with contextlib.suppress(FileNotFoundError):
        os.unlink(tmp)
    raw = data.encode() if isinstance(data, str) else data
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW | _CLOEXEC, 0o644)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(raw)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, p)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    fsync_dir(p.parent)
    return p


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def stale_temporaries(parent: Path, prefix: str) -> list[Path]:
    """Folders ``parent/<prefix><pid>`` left by writers that are no longer running."""
    if not parent.is_dir():
        return []
    out = []
    for p in parent.glob(f"{prefix}*"):
        pid = p.name[len(prefix):]
        if pid.isdigit() and int(pid) != os.getpid() and not _alive(int(pid)) and p.is_dir() \
                and not p.is_symlink():
            out.append(p)
    return out


class NewPolicyFolder:
    """A new policy folder ``out`` that one command makes (module docstring): entering checks it
    (:func:`check_new_folder`, ``option`` names it in errors), takes its lock (the file
    ``.<name>.lock`` beside it, released by the kernel when the process ends, even on kill -9)
    and removes the staging folders of killed writers; :meth:`write` writes it once. Use it
    around the whole work so that a second writer is refused before doing any."""

    def __init__(self, out: str | Path, option: str = "--out") -> None:
        if _names_no_folder(out):
            check_new_folder(out, option)   # the one-line refusal of an empty name
        self.path = Path(out)
        self.option = option
        self._fd: int | None = None
        self._held = False

    @property
    def _lock(self) -> Path:
        return self.path.parent / f".{self.path.name}.lock"

    @property
    def staging(self) -> Path:
        """This process's staging folder, beside the destination."""
        return self.path.parent / f".{self.path.name}.tmp-{os.getpid()}"

    def __enter__(self) -> NewPolicyFolder:
        check_new_folder(self.path, self.option)
        self._take_lock()
        try:
            check_new_folder(self.path, self.option)   # again, now that it is ours
            for old in stale_temporaries(self.path.parent, f".{self.path.name}.tmp-"):
                shutil.rmtree(old, ignore_errors=True)
        except BaseException:
            self._release()
            raise
        self._held = True
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self._release()

    def _busy(self, fd: int) -> ValueError:
        owner = ""
        with contextlib.suppress(OSError):
            owner = os.pread(fd, 400, 0).decode(errors="replace").strip()
        return ValueError(f"{self.option} {str(self.path)!r} is being written by another command "
                          f"({owner or 'owner unknown'}); wait for it to finish or give another "
                          "folder")

    def _take_lock(self) -> None:
        try:
            import fcntl
        except ImportError:  # pragma: no cover - Windows: no advisory locks; best effort
            return
        path = self._lock
        for _ in range(5):
            try:
                fd = os.open(path, os.O_RDWR | os.O_CREAT | _NOFOLLOW | _CLOEXEC, 0o644)
            except OSError as exc:
                raise ValueError(f"{self.option} {str(self.path)!r}: its lock {str(path)!r} "
                                 f"cannot be taken ({exc.strerror or exc}; a symbolic link "
                                 "there is never followed)") from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                err = self._busy(fd)
                os.close(fd)
                raise err from None
            try:   # the file locked is still the one at the path (its last holder removes it)
                st, now = os.fstat(fd), os.lstat(path)
                same = (st.st_dev, st.st_ino) == (now.st_dev, now.st_ino)
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        else:
            raise ValueError(f"{self.option} {str(self.path)!r} is being written by another "
                             "command; wait for it to finish or give another folder")
        stamp = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"pid {os.getpid()} on {socket.gethostname()}, since {stamp}".encode(), 0)
        self._fd = fd

    def _release(self) -> None:
        self._held = False
        fd, self._fd = self._fd, None
        if fd is None:
            return
        with contextlib.suppress(OSError):
            st, now = os.fstat(fd), os.lstat(self._lock)
            if (st.st_dev, st.st_ino) == (now.st_dev, now.st_ino):
                os.unlink(self._lock)
        os.close(fd)

    def write(self, write_files: WriteFiles) -> Path:
        """Write the folder: ``write_files(staging)`` writes its files (regular files only, no
        ``metadata.json``) into the staging folder and returns the metadata; this adds the
        files' sha256 (``files``) and writes ``metadata.json`` last, flushes everything, verifies
        it and renames the staging folder into place. On any error the staging folder is
        removed and nothing is at ``out``. Returns ``out``."""
        from .checkpoint import META, read_meta, sha256, verify_files

        if not self._held:
            raise RuntimeError(f"{str(self.path)!r} is written inside `with NewPolicyFolder(...)`")
        tmp = self.staging
        with contextlib.suppress(FileNotFoundError):
            if os.path.islink(tmp) or not os.path.isdir(tmp):
                os.unlink(tmp)
            else:
                shutil.rmtree(tmp)
        tmp.mkdir()
        try:
            meta = write_files(tmp)
            names = sorted(p.name for p in tmp.iterdir())
            if META in names:
                raise RuntimeError(f"a policy folder's writer wrote {META} itself")
            for name in names:
                if not stat.S_ISREG(os.lstat(tmp / name).st_mode):
                    raise RuntimeError(f"a policy folder's writer made {name!r}, which is not a "
                                       "regular file")
            files = {name: sha256(tmp / name) for name in names}
            (tmp / META).write_text(json.dumps({**meta, "files": files}, indent=2,
                                               default=str) + "\n")
            for name in (*names, META):
                fsync_file(tmp / name)
            fsync_dir(tmp)
            verify_files(tmp, read_meta(tmp))
            check_new_folder(self.path, self.option)   # still absent or an empty folder
            os.rename(tmp, self.path)   # replaces an empty folder atomically; never a link
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
        fsync_dir(self.path.parent)
        return self.path


def write_policy_folder(out: str | Path | NewPolicyFolder, write_files: WriteFiles,
                        option: str = "--out") -> Path:
    """Write the new policy folder ``out`` at once (:class:`NewPolicyFolder`; ``out`` may be one
    already held): ``write_files(staging)`` writes its files and returns its metadata."""
    if isinstance(out, NewPolicyFolder):
        return out.write(write_files)
    with NewPolicyFolder(out, option) as folder:
        return folder.write(write_files)
