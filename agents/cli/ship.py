"""The commands that make and keep the shipped policies: ``ship`` (a training run's policy into
``agents/policies/<env id>/<name>/``, then its records) and ``record`` (re-record the shipped
policies' evaluations: summaries in each ``metadata.json``, every episode in ``episodes.json``)."""
from __future__ import annotations

import argparse
from typing import Any

from microconveyor_env.cli.base import command, emit

ROOT_HELP = ("the folder of shipped policies, laid out as <env id>/<name>/ (default: the "
             "package's agents/policies)")


def _item(text: str) -> tuple[str, str]:
    """``ENV_ID/NAME``: a shipped policy's env id and name."""
    env_id, sep, name = text.partition("/")
    if not sep or not env_id or not name or "/" in name or name in (".", ".."):
        raise argparse.ArgumentTypeError(f"{text!r}: give ENV_ID/NAME, e.g. "
                                         "MicroConveyor-v1/ppo")
    return env_id, name


def _record_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("policies", nargs="*", type=_item, metavar="ENV_ID/NAME",
                   help="the shipped policies to record (default: every one)")
    p.add_argument("--root", default=None, help=ROOT_HELP)


def _ship_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("run", help="a training run folder (`microconveyor train --env ID --out RUN`): "
                               "its model.zip, normalization.json and metadata.json")
    p.add_argument("policy", type=_item, metavar="ENV_ID/NAME",
                   help="where to ship it (an existing folder's files are replaced)")
    p.add_argument("--root", default=None, help=ROOT_HELP)


@command("record", "re-record the shipped policies' evaluations on their fixed targets (each "
                   "folder loaded first; its records and metadata written whole)", _record_args)
def cmd_record(args: argparse.Namespace) -> None:
    """Records each policy (``agents.rl.artefacts.shipping.record``) and prints its summaries."""
    from ..rl.artefacts.shipping import record
    from ..rl.artefacts.shipped import shipped_policies

    wanted = args.policies or [(e, n) for e, names in shipped_policies(args.root).items()
                               for n in names]
    out: dict[str, Any] = {}
    for env_id, name in wanted:
        out[f"{env_id}/{name}"] = record(env_id, name, args.root)
    emit(args, {"recorded": out})


@command("ship", "ship a training run's policy as agents/policies/ENV_ID/NAME (loaded first, "
                 "staged and loaded before it replaces anything) and record its evaluations",
         _ship_args)
def cmd_ship(args: argparse.Namespace) -> None:
    """Ships (``agents.rl.artefacts.shipping.ship``), then records, the policy."""
    from ..rl.artefacts.shipping import record, ship

    env_id, name = args.policy
    folder = ship(args.run, env_id, name, args.root)
    emit(args, {"folder": str(folder), "recorded": record(env_id, name, args.root)})
