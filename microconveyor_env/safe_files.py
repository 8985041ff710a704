"""Reading files a user may have received from others (policy folders, presets), within bounds.

Every read here is of a **regular file** (a FIFO, a device such as ``/dev/zero``, a directory or a
symbolic link is refused before a byte is read), of at most a stated number of bytes (checked on
the open file before reading, and again while reading, so a file that grows is cut off), named by
a **plain file name** inside its folder where a folder is given (no ``/``, no ``..``, not
absolute). A zip archive's entries are checked the same way: plain names, no duplicates, each
entry's declared size and the archive's total within limits before anything is decompressed.
Failures are one :class:`UnsafeFileError` naming the file.

Package infrastructure: it imports no room of the package.
"""
from __future__ import annotations

import io
import os
import stat
import zipfile
from pathlib import Path

KiB, MiB = 1 << 10, 1 << 20


class UnsafeFileError(ValueError):
    """A file that is not a regular file within its size limit, or a name that leaves its
    folder."""


class NotTextError(UnsafeFileError):
    """A file that was read but is not UTF-8 text."""


def plain_name(name: object, what: str = "file name") -> str:
    """``name`` if it is a plain file name (a non-empty string without a path separator, not
    ``.``/``..``, no NUL); else :class:`UnsafeFileError`."""
    if (not isinstance(name, str) or not name or name in (".", "..") or "/" in name
            or "\\" in name or "\x00" in name or os.path.isabs(name)):
        raise UnsafeFileError(f"{what} {name!r} is not a plain file name (a name inside the "
                              "folder, without a path)")
    return name


def kind_of(mode: int) -> str:
    """What a file of ``stat`` mode ``mode`` is, in words (for a message)."""
    for test, word in ((stat.S_ISLNK, "a symbolic link"), (stat.S_ISDIR, "a folder"),
                       (stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return word
    return "not a regular file"


def read_bytes(path: str | Path, limit: int, folder: str | Path | None = None,
               follow_symlinks: bool = False) -> bytes:
    """The bytes of the regular file ``path`` (with ``folder``: ``folder/path``, ``path`` a plain
    name), at most ``limit`` of them. FIFOs and devices are refused without being read or
    blocked on, and so are symbolic links (with ``follow_symlinks``: a link to a regular file is
    read as that file); so is a file larger than ``limit``."""
    if folder is not None:
        path = Path(folder) / plain_name(str(path))
    path = Path(path)
    try:
        st = os.stat(path) if follow_symlinks else os.lstat(path)
    except FileNotFoundError:
        raise UnsafeFileError(f"{str(path)!r} does not exist") from None
    except OSError as exc:
        raise UnsafeFileError(f"{str(path)!r} cannot be read ({exc.strerror})") from None
    if not stat.S_ISREG(st.st_mode):
        raise UnsafeFileError(f"{str(path)!r} is {kind_of(st.st_mode)}; only a regular file is "
                              "read")
    if st.st_size > limit:
        raise UnsafeFileError(f"{str(path)!r} is too large ({st.st_size:,} bytes; at most "
                              f"{limit:,})")
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0)
    if not follow_symlinks:
        flags |= getattr(os, "O_NOFOLLOW", 0)
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        raise UnsafeFileError(f"{str(path)!r} cannot be read ({exc.strerror})") from None
    with os.fdopen(fd, "rb") as fh:
        st = os.fstat(fh.fileno())        # the file opened: replaced since the lstat?
        if not stat.S_ISREG(st.st_mode):
            raise UnsafeFileError(f"{str(path)!r} is {kind_of(st.st_mode)}; only a regular file "
                                  "is read")
        data = fh.read(limit + 1)
    if len(data) > limit:
        raise UnsafeFileError(f"{str(path)!r} is too large (more than {limit:,} bytes)")
    return data


def read_text(path: str | Path, limit: int, folder: str | Path | None = None,
              follow_symlinks: bool = False) -> str:
    """:func:`read_bytes` decoded as UTF-8 (:class:`UnsafeFileError` if it is not)."""
    data = read_bytes(path, limit, folder, follow_symlinks)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        where = Path(folder) / str(path) if folder is not None else Path(path)
        raise NotTextError(f"{str(where)!r} is not UTF-8 text ({exc.reason} at byte "
                              f"{exc.start})") from None


class BoundedZip:
    """A zip archive read from memory with its entries checked before any is decompressed:
    plain names, none twice, each entry's declared size at most ``entry_limit`` and all of them
    together at most ``total_limit``. :meth:`read` returns an entry's bytes (never more than its
    declared size: :mod:`zipfile` stops there and checks the CRC)."""

    def __init__(self, data: bytes, where: str, entry_limit: int, total_limit: int) -> None:
        self.where = where
        try:
            self._zip = zipfile.ZipFile(io.BytesIO(data))
            infos = self._zip.infolist()
        except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, ValueError,
                EOFError) as exc:
            raise UnsafeFileError(f"{where} is not a readable zip archive ({exc})") from None
        seen: set[str] = set()
        total = 0
        for info in infos:
            plain_name(info.filename, f"{where}: entry")
            if info.filename in seen:
                raise UnsafeFileError(f"{where}: entry {info.filename!r} appears twice")
            seen.add(info.filename)
            if info.file_size > entry_limit:
                raise UnsafeFileError(f"{where}: entry {info.filename!r} would inflate to "
                                      f"{info.file_size:,} bytes (at most {entry_limit:,})")
            total += info.file_size
        if total > total_limit:
            raise UnsafeFileError(f"{where}: its entries would inflate to {total:,} bytes (at "
                                  f"most {total_limit:,})")
        self.infos = {info.filename: info for info in infos}

    @property
    def names(self) -> list[str]:
        return list(self.infos)

    def read(self, name: str) -> bytes:
        if name not in self.infos:
            raise UnsafeFileError(f"{self.where} has no entry {name!r}")
        try:
            return self._zip.read(self.infos[name])
        except (zipfile.BadZipFile, OSError, ValueError, EOFError, NotImplementedError,
                RuntimeError) as exc:
            raise UnsafeFileError(f"{self.where}: entry {name!r} cannot be read ({exc})") \
                from None

    def close(self) -> None:
        self._zip.close()
