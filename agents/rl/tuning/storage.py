"""The Optuna storage a study lives in: its URL (default, shown with its secrets masked wherever
it is printed, its driver checked), opening it (heartbeats, timeouts, the schema race) and its
errors as one line."""
from __future__ import annotations

import contextlib
import os
import random
import re
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

HEARTBEAT_S = 60            # a running trial's heartbeat (a new study's default) [s]
GRACE = 3                   # a trial without a heartbeat for GRACE x the interval is stale
SCHEMA_TRIES = 10           # attempts at opening a storage whose tables another process creates
CONNECT_TIMEOUT_S = 10      # a database server that does not answer within this is unreachable

STORAGE_ENV = "MICROCONVEYOR_TUNE_STORAGE"  # the storage URL when none is given (keeps a
                                           # database password out of the command line)


def default_storage(out: str | Path) -> str:
    """``$MICROCONVEYOR_TUNE_STORAGE`` if set, else SQLite in ``out``."""
    return os.environ.get(STORAGE_ENV) or f"sqlite:///{Path(out) / 'optuna.db'}"


# a query parameter or key=value pair that holds a secret (password=, passwd=, sslpassword=,
# pwd=, secret=, token=, ...) and its value, quoted or not
# (ending before a separator, or before a colon, comma, full stop or bracket that ends a clause)
_SECRET_PAIR = re.compile(r"(?i)\b([\w.-]*(?:pass(?:word|wd)?|pwd|secret|token)[\w.-]*)"
                          r"(\s*=\s*)('[^']*'|\"[^\"]*\"|[^&;\s#]+?(?=[:,.)]{0,2}(?:[&;\s#]|$)))")
# a URL's userinfo password: USER:PASSWORD@ (with or without a scheme before it)
_USERINFO = re.compile(r"([^\s:/@?#]*:)([^\s@/?#]*)@")
MASK = "***"


def _secrets(url: str) -> set[str]:
    """The secrets a storage URL holds (as written and percent-decoded): its userinfo password
    and the values of its password-like query parameters, found whether it parses or not."""
    from urllib.parse import unquote

    found = {m.group(2) for m in _USERINFO.finditer(url)}
    found |= {m.group(3).strip("'\"") for m in _SECRET_PAIR.finditer(url)}
    try:
        from sqlalchemy.engine import make_url

        u = make_url(url)
        found.add(str(u.password or ""))
        for key, value in u.query.items():
            if _SECRET_PAIR.match(f"{key}=x"):
                found |= {value} if isinstance(value, str) else set(value)
    except Exception:  # noqa: BLE001 - a URL sqlalchemy cannot parse: the patterns found them
        pass
    found |= {unquote(f) for f in found}
    return {f for f in found if len(f) >= 3 and f != MASK}


def mask(text: str, url: str | None = None) -> str:
    """``text`` with every secret masked: URL passwords (``USER:PASSWORD@``), password-like
    parameters (``password=...``) and, given the storage ``url``, its secrets wherever they
    appear (an error message that quotes one)."""
    out = _USERINFO.sub(lambda m: f"{m.group(1)}{MASK}@", text)
    out = _SECRET_PAIR.sub(lambda m: f"{m.group(1)}{m.group(2)}{MASK}", out)
    for secret in sorted(_secrets(url) if url else (), key=len, reverse=True):
        out = out.replace(secret, MASK)
    return out


def shown(url: str) -> str:
    """``url`` as printed: its secrets masked (the userinfo password, password-like query
    parameters), also in a URL that does not parse."""
    from sqlalchemy.engine import make_url

    try:
        text = make_url(url).render_as_string(hide_password=True)
    except Exception:  # noqa: BLE001 - not a URL sqlalchemy parses: check_storage says so
        text = url
    return mask(text, url)


def masked(value: Any, url: str) -> Any:
    """``value`` (a result: dicts, lists, strings) with :func:`mask` applied to every string."""
    if isinstance(value, str):
        return mask(value, url)
    if isinstance(value, dict):
        return {masked(k, url): masked(v, url) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [masked(v, url) for v in value]
    return value


@contextlib.contextmanager
def secrets_masked(url: str) -> Iterator[None]:
    """Re-raise any error raised inside whose message shows a secret of ``url`` as a ValueError
    with the secret masked (another error's type is named in the message)."""
    try:
        yield
    except Exception as exc:
        text = str(exc)
        safe = mask(text, url)
        if safe == text:
            raise
        if isinstance(exc, ValueError):
            raise ValueError(safe) from None
        raise ValueError(f"{type(exc).__name__}: {safe}") from None


# database drivers a storage URL may need: module -> what to pip install
DRIVERS = {"psycopg": "'psycopg[binary]'", "psycopg2": "psycopg2-binary", "pymysql": "pymysql",
           "MySQLdb": "mysqlclient", "pg8000": "pg8000", "asyncpg": "asyncpg"}


def _engine_url(url: str) -> str:
    """The URL SQLAlchemy opens: ``postgresql://`` without a driver means psycopg (v3, the
    ``agents`` extra's driver) where it is installed, as SQLAlchemy 2.1 reads it (2.0 would
    look for psycopg2)."""
    import importlib.util

    from sqlalchemy.engine import make_url

    u = make_url(url)
    if u.drivername == "postgresql" and importlib.util.find_spec("psycopg") is not None:
        return u.set(drivername="postgresql+psycopg").render_as_string(hide_password=False)
    return url


def check_storage(url: str) -> None:
    """Refuse, without connecting, a storage URL that cannot work (ValueError naming it, its
    password masked): not a database URL, SQLite in memory (the workers are other processes and
    the study would end with the command), a database driver that is not installed (naming the
    package to install)."""
    with secrets_masked(url):
        _check_storage(url)


def _check_storage(url: str) -> None:
    from sqlalchemy import create_engine
    from sqlalchemy.engine import make_url

    where = shown(url)
    try:
        u = make_url(url)
    except Exception as exc:  # noqa: BLE001 - sqlalchemy's ArgumentError
        raise ValueError(f"cannot open the Optuna storage {where}: not a database URL "
                         f"({exc})") from None
    if u.get_backend_name() == "sqlite" and (u.database in (None, "", ":memory:")
                                             or u.query.get("mode") == "memory"):
        raise ValueError(f"the storage {where} is an SQLite database in memory: the workers "
                         "(other processes) cannot share it and it ends with the command; give "
                         "a file, sqlite:///PATH (or leave --storage out: OUT/optuna.db)")
    try:
        create_engine(_engine_url(url)).dispose()  # imports the driver; connects to nothing
    except ImportError as exc:
        mod = exc.name or ""
        pkg = DRIVERS.get(mod.split(".")[0], mod)
        extra = (" (the 'agents' extra has it: pip install 'microconveyor-env[agents]')"
                 if mod == "psycopg" else "")
        raise ValueError(f"the storage {where} needs the database driver {mod!r}, which is not "
                         f"installed: pip install {pkg}{extra}") from None
    except Exception as exc:  # noqa: BLE001 - an unknown dialect, a bad argument
        raise ValueError(f"cannot open the Optuna storage {where}: {type(exc).__name__}: "
                         f"{_first_line(exc)}") from None


def _first_line(exc: BaseException) -> str:
    """A database error's own message (the driver's, without SQLAlchemy's SQL and links)."""
    text = str(getattr(exc, "orig", None) or exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _db_error(exc: BaseException) -> BaseException | None:
    """The database error behind ``exc`` (its causes and contexts searched): SQLAlchemy's, else
    Optuna's StorageInternalError; None if ``exc`` does not come from the storage."""
    from optuna.exceptions import StorageInternalError
    from sqlalchemy.exc import SQLAlchemyError

    found: BaseException | None = None
    seen: set[int] = set()
    e: BaseException | None = exc
    while e is not None and id(e) not in seen:
        seen.add(id(e))
        if isinstance(e, SQLAlchemyError):
            return e
        if isinstance(e, StorageInternalError) and found is None:
            found = e
        e = e.__cause__ if e.__cause__ is not None else (
            None if e.__suppress_context__ else e.__context__)
    return found


def _schema_race(exc: BaseException) -> bool:
    """Whether ``exc`` is what creating a storage's tables raises while another process creates
    them: a duplicate key, table or type (PostgreSQL SQLSTATE 23505, 42P07, 42710), SQLite's and
    MySQL's "already exists"."""
    from sqlalchemy import exc as sa

    err = _db_error(exc)
    if isinstance(err, sa.IntegrityError):
        return True
    if isinstance(err, (sa.ProgrammingError, sa.OperationalError)):
        orig = getattr(err, "orig", None)
        code = getattr(orig, "sqlstate", None) or getattr(orig, "pgcode", None)
        return code in ("23505", "42P07", "42710") or "already exists" in str(orig).lower()
    return False


def open_storage(url: str, heartbeat_s: int | None = HEARTBEAT_S) -> Any:
    """An Optuna RDB storage at ``url``: trials send a heartbeat every ``heartbeat_s`` s (None:
    no heartbeat) and are stale after :data:`GRACE` times that; a heartbeat the storage cannot
    take (the server away) is tried again at the next beat instead of ending the trial. SQLite
    waits up to 60 s for a lock; a database server gets :data:`CONNECT_TIMEOUT_S` s to answer
    and every pooled connection is checked before use (a restarted server costs no error).
    Creating the tables while another process creates them is retried."""
    import warnings

    import optuna
    from sqlalchemy.engine import make_url

    optuna.logging.set_verbosity(optuna.logging.WARNING)  # our own line per trial instead
    backend = make_url(url).get_backend_name()
    kw: dict[str, Any] = ({"connect_args": {"timeout": 60}} if backend == "sqlite" else
                          {"pool_pre_ping": True})
    if backend in ("postgresql", "mysql"):
        kw["connect_args"] = {"connect_timeout": CONNECT_TIMEOUT_S}
    beat_s = None if heartbeat_s is None else int(heartbeat_s)
    for attempt in range(SCHEMA_TRIES):
        try:
            with warnings.catch_warnings():  # heartbeats are "experimental" (since Optuna 2.9)
                warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
                storage = optuna.storages.RDBStorage(
                    _engine_url(url), engine_kwargs=kw, heartbeat_interval=beat_s,
                    grace_period=None if beat_s is None else GRACE * beat_s)
            break
        except Exception as exc:
            if attempt + 1 == SCHEMA_TRIES or not _schema_race(exc):
                raise
            time.sleep(random.uniform(0.05, 0.25) * (attempt + 1))  # the other one finishes
    beat = storage.record_heartbeat

    def record_heartbeat(trial_id: int) -> None:
        try:
            beat(trial_id)
        except Exception as exc:
            if _db_error(exc) is None:
                raise
            # the storage is away: the trial notices when it next writes; beat again later
    storage.record_heartbeat = record_heartbeat  # type: ignore[method-assign]
    return storage


class StorageLost(BaseException):
    """Raised out of a trial when its storage fails: a BaseException, so that Optuna does not
    try to record the trial's failure in the storage that just failed."""


@contextlib.contextmanager
def storage_errors(url: str, opening: bool = False) -> Iterator[None]:
    """Turn an error of the storage at ``url`` (raised inside, however wrapped) into one
    ValueError naming it (password masked): ``cannot open`` it (``opening``) or ``lost`` it."""
    try:
        yield
    except (Exception, StorageLost) as exc:
        err = _db_error(exc)
        if err is None:
            raise
        what = mask(f"{type(err).__name__}: {_first_line(err)}", url)
        if opening:
            raise ValueError(f"cannot open the Optuna storage {shown(url)}: {what}") from None
        raise ValueError(f"lost the Optuna storage {shown(url)} ({what}); the study is kept "
                         "there: run the command again once the storage is back") from None
