"""Connecting to an existing Dask scheduler, bounded and checked.

distributed has no timeout on the handshake it reads after connecting, and a server that is not a
Dask scheduler (an HTTP server) can make it hang or read a 3 EiB "message length". Before a
``Client`` is made, :func:`check_scheduler` asks the address for its ``identity`` on a private
event loop, the whole exchange bounded by a timeout, and says in one line what it found.
"""
from __future__ import annotations

import asyncio
import threading
from collections.abc import Coroutine
from typing import Any

from ..physics.materials import ParameterError

SCHEDULER_TIMEOUT_S = 10.0  # default bound on connecting to an existing scheduler [s]


class SchedulerConnectionError(ConnectionError):
    """No Dask scheduler answered at the given address in time, or what answered is not one."""


def check_scheduler(address: str, timeout: float = SCHEDULER_TIMEOUT_S) -> dict[str, Any]:
    """The identity of the Dask scheduler at ``address`` (``tcp://host:port``), asked within
    ``timeout`` [s]; raises :class:`SchedulerConnectionError` if nothing answers in time or what
    answers is not a Dask scheduler (e.g. an HTTP server, whose reply distributed would read as an
    exabyte-long message).

    Runs on a private event loop in a helper thread, so it works whether or not the caller runs
    one.
    """
    timeout = _positive_timeout(timeout)
    _check_address(address)
    try:
        ident = _in_thread(_identity(address, timeout))
    except TimeoutError as exc:
        raise SchedulerConnectionError(no_answer(address, timeout)) from exc
    except OSError as exc:  # refused/unreachable until the timeout, or the peer hung up
        if "Timed out" in str(exc):
            raise SchedulerConnectionError(no_answer(address, timeout, exc.__cause__)) from exc
        raise SchedulerConnectionError(f"{address} is not a Dask scheduler: the connection "
                                       f"failed ({_brief(exc)})") from exc
    except Exception as exc:  # noqa: BLE001 - a reply read as Dask frames: any error
        raise SchedulerConnectionError(  # e.g. MemoryError: "HTTP/1.0" read as a frame length
            f"{address} is not a Dask scheduler: its reply is not a Dask message (an HTTP or "
            "other server?)") from exc
    if not isinstance(ident, dict) or ident.get("type") != "Scheduler":
        kind = ident.get("type") if isinstance(ident, dict) else None
        raise SchedulerConnectionError(f"{address} is not a Dask scheduler"
                                       + (f" (it is a Dask {kind})" if kind else ""))
    return ident


def _check_address(address: str) -> None:
    """Raise :class:`ParameterError` unless ``address`` is a Dask address (a known scheme; a port
    for the network ones)."""
    from distributed.comm.addressing import parse_address, parse_host_port
    from distributed.comm.registry import get_backend

    try:
        scheme, loc = parse_address(address)
        get_backend(scheme)
        if scheme in ("tcp", "tls", "ws", "wss"):
            parse_host_port(loc)
    except (ValueError, TypeError) as exc:
        raise ParameterError(f"scheduler address {address!r} is invalid ({exc}); expected e.g. "
                             "tcp://10.0.0.5:8786") from exc


def _in_thread(coro: Coroutine[Any, Any, Any]) -> Any:
    """``asyncio.run(coro)`` in a daemon thread (a private event loop): its result, or its
    exception raised here. A Ctrl-C interrupts the wait at once, and the thread never delays the
    interpreter's exit."""
    box: dict[str, Any] = {}

    def target() -> None:
        try:
            box["result"] = asyncio.run(coro)
        except BaseException as exc:  # noqa: BLE001 - handed to the caller
            box["error"] = exc

    thread = threading.Thread(target=target, name="check-scheduler", daemon=True)
    thread.start()
    thread.join()
    if "error" in box:
        raise box["error"]
    return box["result"]


async def _identity(address: str, timeout: float) -> Any:
    """The reply to the ``identity`` request at ``address``, all within about ``timeout`` [s]
    (distributed bounds the connection, not the handshake that follows)."""
    from distributed.comm import connect

    async def ask() -> Any:
        comm = await connect(address, timeout=timeout)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    return await asyncio.wait_for(ask(), 1.05 * timeout + 0.1)  # connect's own error first


def no_answer(address: str, timeout: float, cause: BaseException | None = None) -> str:
    """The message for a scheduler that did not answer within ``timeout`` [s]."""
    text = str(cause).rsplit(": ", 1)[-1].strip() if cause is not None else ""
    last = f" (last error: {text})" if text and not isinstance(cause, TimeoutError) else ""
    return (f"no Dask scheduler answered at {address} within {timeout:g} s{last}: is the address "
            "right and a scheduler running there?")


def _brief(exc: BaseException) -> str:
    """``exc`` as one short line."""
    return " ".join(f"{type(exc).__name__}: {exc}".split())[:200]


def _positive_timeout(timeout: float) -> float:
    """``timeout`` [s] checked: positive and finite."""
    t = float(timeout)
    if not t > 0 or t == float("inf"):
        raise ParameterError(f"scheduler timeout = {timeout!r} s is invalid: must be > 0 and "
                             "finite")
    return t


