"""A new policy folder: whether it can be written (before any work), and the temporary folders
that writers killed before renaming theirs into place left behind."""
from __future__ import annotations

import os
from pathlib import Path


def occupied(folder: str | Path) -> bool:
    """Whether ``folder`` exists as anything but an empty folder (a new policy folder's check);
    a symbolic link, dangling or not, counts as occupied."""
    path = Path(folder)
    if path.is_symlink():
        return True
    return path.exists() and (not path.is_dir() or any(path.iterdir()))


def check_new_folder(folder: str | Path, option: str = "--out") -> None:
    """Refuse, before any work, a folder a new policy cannot be written to: one that exists and
    is not an empty folder, a symbolic link, or a place whose parent folder cannot be created
    or written (checked by writing and removing a probe file). ValueError naming ``option``."""
    path = Path(folder)
    if occupied(path):
        what = "is a symbolic link" if path.is_symlink() else "exists and is not empty"
        raise ValueError(f"{option} {str(path)!r} {what}; give a new folder")
    parent = path.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
        probe = parent / f".{path.name}.probe-{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise ValueError(f"{option} {str(path)!r} cannot be written: {str(parent)!r} "
                         f"({exc.strerror or exc})") from None


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
