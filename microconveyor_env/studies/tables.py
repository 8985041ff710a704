"""The studies' tidy tables: one row per simulation, parameters as columns; written atomically
(``.csv`` or ``.parquet``), read back, and compared row for row."""
from __future__ import annotations

import os
import secrets
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..physics.materials import ParameterError

if TYPE_CHECKING:
    import pandas as pd

Row = dict[str, Any]    # one table row: parameters and results, SI units in the key names

TIMING_COLUMNS = ("wall_time_s",)  # measured, not computed: excluded when comparing runs
TABLE_SUFFIXES = (".csv", ".parquet")  # the table formats of :func:`write_table`


def write_table(rows: list[Row], path: str | Path) -> Path:
    """Write rows as a tidy table: ``.csv`` or ``.parquet`` (one row per simulation).

    The table goes to a temporary file in the same folder, renamed onto ``path`` when complete
    (:func:`os.replace`), so ``path`` never holds a partial table (an interrupted write leaves
    nothing)."""
    import pandas as pd

    path = Path(path)
    if path.suffix not in TABLE_SUFFIXES:
        raise ParameterError(f"table file {str(path)!r}: use a .csv or .parquet name")
    path.parent.mkdir(parents=True, exist_ok=True)
    df = pd.DataFrame(rows)
    with atomic_path(path) as tmp:
        if path.suffix == ".parquet":
            df.to_parquet(tmp, index=False)
        else:
            df.to_csv(tmp, index=False)
    return path


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """A temporary file name beside ``path`` (same suffix, so writers infer the same format) to
    write into; on a clean exit it is renamed onto ``path``, on any exception (Ctrl-C included)
    it is removed."""
    path = Path(path)
    tmp = partial_path(path)
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def partial_path(path: str | Path) -> Path:
    """A fresh temporary name beside ``path`` for its content while being written: hidden, with
    the same suffix (so writers infer the same format), unique to this process and call."""
    path = Path(path)
    return path.with_name(f".{path.name}.{os.getpid()}-{secrets.token_hex(4)}"
                          f".partial{path.suffix}")


def read_table(path: str | Path) -> pd.DataFrame:
    """A table written by :func:`write_table` (``.parquet``, else CSV)."""
    import pandas as pd

    path = Path(path)
    return pd.read_parquet(path) if path.suffix == ".parquet" else pd.read_csv(path)


def same_rows(a: Sequence[Row], b: Sequence[Row]) -> bool:
    """Whether two row lists are identical, row for row, ignoring :data:`TIMING_COLUMNS`."""
    if len(a) != len(b):
        return False
    for ra, rb in zip(a, b, strict=True):
        ka = {k: v for k, v in ra.items() if k not in TIMING_COLUMNS}
        kb = {k: v for k, v in rb.items() if k not in TIMING_COLUMNS}
        if ka.keys() != kb.keys():
            return False
        for k in ka:
            x, y = ka[k], kb[k]
            if x != y and not (_isnan(x) and _isnan(y)):
                return False
    return True


def _isnan(v: object) -> bool:
    return isinstance(v, float) and v != v
