"""Checkpoints that survive a kill, and the lock that keeps two trainings out of one folder.

A checkpoint is one **generation**: a folder ``OUT/checkpoints/gen-<steps>`` holding
``model.zip``, ``normalization.json`` and ``metadata.json`` (which records the sha256 of the other
two). It is written in a temporary folder, every file flushed to disk, read back and verified, and
only then renamed into place (an atomic rename); the previous generation is deleted only after the
new one is in place. A kill at any moment therefore leaves the newest complete generation intact
(at most one checkpoint interval of training is lost), and a full disk fails the write of the new
generation without touching the old. :func:`latest` picks the newest generation that verifies.

The final policy files in ``OUT`` are replaced one by one with atomic renames, the model removed
first and put in place last (after ``metadata.json`` with the hashes), so a folder caught between
two versions holds no model and loads as no policy instead of half old, half new
(:func:`replace_files`).
"""
from __future__ import annotations

import contextlib
import datetime
import hashlib
import json
import os
import shutil
import socket
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from collections.abc import Callable, Iterator

CHECKPOINTS = "checkpoints"
GEN_PREFIX = "gen-"
TMP_PREFIX = ".tmp-"
LOCK = ".lock"
MODEL, NORMALIZATION, META = "model.zip", "normalization.json", "metadata.json"
KEEP = 2  # complete generations kept: the newest and the one before it
META_LIMIT = 16 << 20      # bytes of metadata.json read (a refinement report is ~100 kB)
LISTED_LIMIT = 1 << 30     # bytes of a file metadata.json lists (hashed as it is read)


class CheckpointError(RuntimeError):
    """A checkpoint that cannot be written, or a folder that cannot be resumed or used."""


def sha256(path: Path) -> str:
    """Hex sha256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _fsync_file(path: Path) -> None:
    with open(path, "rb") as fh:
        os.fsync(fh.fileno())


def _fsync_dir(path: Path) -> None:
    with contextlib.suppress(OSError):  # not every platform can fsync a directory
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def verify_files(folder: Path, meta: dict[str, Any]) -> None:
    """Check that every file ``meta["files"]`` lists exists in ``folder`` with its recorded
    sha256; one :class:`CheckpointError` naming the first file that does not."""
    import stat

    from microconveyor_env.safe_files import UnsafeFileError, kind_of, plain_name

    files = meta.get("files")
    if not isinstance(files, dict) or not files:
        raise CheckpointError(f"{str(folder / META)!r} lists no files with their sha256")
    for name, digest in files.items():
        try:
            plain_name(name, f"{META} lists a file")
        except UnsafeFileError as exc:
            raise CheckpointError(f"{str(folder / META)!r}: {exc}") from None
        path = folder / name
        try:
            st = os.lstat(path)
        except OSError:
            raise CheckpointError(f"{str(path)!r} is missing (listed in {META})") from None
        if not stat.S_ISREG(st.st_mode):
            raise CheckpointError(f"{str(path)!r} is {kind_of(st.st_mode)}; only a regular "
                                  f"file is read (listed in {META})")
        if st.st_size > LISTED_LIMIT:
            raise CheckpointError(f"{str(path)!r} is too large ({st.st_size:,} bytes; at most "
                                  f"{LISTED_LIMIT:,}; listed in {META})")
        if not isinstance(digest, str) or sha256(path) != digest:
            raise CheckpointError(f"{str(path)!r} is not the file {META} describes (sha256 "
                                  "differs): the folder was changed or written only in part")


def read_meta(folder: Path) -> dict[str, Any]:
    """``folder/metadata.json`` as a dict; :class:`CheckpointError` if missing or damaged."""
    from microconveyor_env.safe_files import UnsafeFileError, read_text

    path = folder / META
    try:
        meta = json.loads(read_text(META, META_LIMIT, folder))
    except UnsafeFileError as exc:
        raise CheckpointError(f"{str(path)!r} is missing or not JSON ({exc})") from None
    except (json.JSONDecodeError, RecursionError) as exc:
        raise CheckpointError(f"{str(path)!r} is missing or not JSON ({exc})") from None
    if not isinstance(meta, dict):
        raise CheckpointError(f"{str(path)!r} is not a JSON object")
    return meta


def write_generation(root: Path, steps: int, meta: dict[str, Any],
                     write_files: Callable[[Path], None]) -> Path:
    """Write one generation for ``steps`` under ``root/checkpoints``: ``write_files(tmp)`` writes
    the model and statistics into a temporary folder, this adds ``metadata.json`` (``meta`` plus
    the files' sha256), flushes, verifies, renames into place and prunes old generations.
    Returns the new generation's folder; on any OSError the temporary folder is removed, the older
    generations are untouched and :class:`CheckpointError` says what failed."""
    ckpts = root / CHECKPOINTS
    ckpts.mkdir(parents=True, exist_ok=True)
    tmp = ckpts / f"{TMP_PREFIX}{steps:012d}-{os.getpid()}"
    final = ckpts / f"{GEN_PREFIX}{steps:012d}"
    try:
        shutil.rmtree(tmp, ignore_errors=True)
        tmp.mkdir()
        write_files(tmp)
        files = {p.name: sha256(p) for p in sorted(tmp.iterdir()) if p.is_file()}
        (tmp / META).write_text(json.dumps({**meta, "steps": int(steps), "files": files},
                                           indent=2, default=str) + "\n")
        for p in tmp.iterdir():
            _fsync_file(p)
        _fsync_dir(tmp)
        verify_files(tmp, read_meta(tmp))
        if final.exists():  # the same step written again (e.g. the final save): replace it
            shutil.rmtree(final)
        os.rename(tmp, final)
        _fsync_dir(ckpts)
    except OSError as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        prev = latest_step(root)
        raise CheckpointError(
            f"checkpoint at step {steps:,} could not be written ({exc.strerror or exc}); "
            + ("no earlier checkpoint exists" if prev is None else
               f"the checkpoint at step {prev:,} is intact: free space and --resume")) from None
    prune(root)
    return final


def generations(root: Path) -> list[Path]:
    """Generation folders under ``root/checkpoints``, newest first (complete or not)."""
    ckpts = root / CHECKPOINTS
    if not ckpts.is_dir():
        return []
    gens = [p for p in ckpts.iterdir() if p.is_dir() and p.name.startswith(GEN_PREFIX)
            and p.name[len(GEN_PREFIX):].isdigit()]
    return sorted(gens, key=lambda p: int(p.name[len(GEN_PREFIX):]), reverse=True)


@dataclass(frozen=True)
class Generation:
    """A complete, verified checkpoint generation."""

    folder: Path
    meta: dict[str, Any]
    skipped: tuple[str, ...]   # newer generations that did not verify, with the reason

    @property
    def steps(self) -> int:
        return int(self.meta["steps"])


def latest(root: Path, check: Callable[[Path, dict[str, Any]], None] | None = None
           ) -> Generation | None:
    """The newest generation whose files verify (and pass ``check(folder, meta)``, which raises
    on a problem), or None when there is none."""
    skipped: list[str] = []
    for gen in generations(root):
        try:
            meta = read_meta(gen)
            verify_files(gen, meta)
            if check is not None:
                check(gen, meta)
        except (CheckpointError, ValueError) as exc:
            skipped.append(f"{gen.name}: {exc}")
            continue
        return Generation(gen, meta, tuple(skipped))
    return None


def latest_step(root: Path) -> int | None:
    """Steps of the newest verified generation (None: none)."""
    gen = latest(root)
    return None if gen is None else gen.steps


def prune(root: Path) -> None:
    """Delete leftover temporary folders of dead writers and all but the :data:`KEEP` newest
    complete generations (damaged ones go too once enough newer complete ones exist)."""
    ckpts = root / CHECKPOINTS
    for p in ckpts.glob(f"{TMP_PREFIX}*"):
        pid = p.name.rsplit("-", 1)[-1]
        if not (pid.isdigit() and int(pid) == os.getpid()):
            shutil.rmtree(p, ignore_errors=True)
    complete = 0
    for gen in generations(root):
        if complete >= KEEP:
            shutil.rmtree(gen, ignore_errors=True)
            continue
        try:
            verify_files(gen, read_meta(gen))
            complete += 1
        except CheckpointError:
            pass


def replace_files(src: Path, dst: Path, names: tuple[str, ...]) -> None:
    """Make ``dst``'s policy files ``src``'s ``names`` (the model, its statistics, the metadata
    with their sha256). The model is removed first and put in place last, so a folder caught in
    between has no model and loads as no policy, never as one model with another's statistics
    or metadata; a policy file of ``dst`` that ``names`` lacks is removed. Each file goes
    through a new temporary file (never through a symbolic link) and an atomic rename."""
    _remove(dst / MODEL)
    _fsync_dir(dst)
    for name in (MODEL, NORMALIZATION, META):
        if name not in names:
            _remove(dst / name)
    for name in sorted(names, key=lambda n: n == MODEL):   # the model last
        tmp = dst / f".{name}.tmp-{os.getpid()}"
        _remove(tmp)
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0),
                     0o644)
        with os.fdopen(fd, "wb") as fh, open(src / name, "rb") as fin:
            shutil.copyfileobj(fin, fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, dst / name)
        _fsync_dir(dst)


def _remove(path: Path) -> None:
    """Remove the file (or link) ``path`` if it is there."""
    with contextlib.suppress(FileNotFoundError):
        os.unlink(path)


@contextlib.contextmanager
def folder_lock(out: Path) -> Iterator[Path]:
    """Hold an exclusive lock on ``out`` for a training (``out/.lock``, with the owner's pid,
    host and start time). The kernel drops the lock when the process ends, even on kill -9, so a
    stale lock file never blocks a later run. A second training into ``out`` gets a
    :class:`CheckpointError` naming the owner."""
    if out.is_symlink():
        raise CheckpointError(f"{str(out)!r} is a symbolic link; give the run folder itself")
    out.mkdir(parents=True, exist_ok=True)
    path = out / LOCK
    try:   # never through a symbolic link
        fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0), 0o644)
    except OSError as exc:
        raise CheckpointError(f"the lock {str(path)!r} cannot be opened ({exc.strerror or exc}; "
                              "a symbolic link there is never followed)") from None
    fh = os.fdopen(fd, "r+")
    try:
        try:
            import fcntl

            fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except ImportError:  # pragma: no cover - Windows: no advisory locks; best effort
            pass
        except OSError:
            fh.seek(0)
            owner = fh.read().strip() or "unknown owner"
            raise CheckpointError(f"{str(out)!r} is in use by another training ({owner}); "
                                  "wait for it to finish or choose another --out") from None
        fh.seek(0)
        fh.truncate()
        fh.write(f"pid {os.getpid()} on {socket.gethostname()}, since "
                 f"{datetime.datetime.now(datetime.UTC).isoformat(timespec='seconds')}")
        fh.flush()
        yield path
    finally:
        fh.close()
