"""Writing a refined policy folder (:mod:`.refine`) beside its source, atomically."""
from __future__ import annotations

from pathlib import Path
from typing import Any

from ..artefacts.folders import NewPolicyFolder
from ..artefacts.policy_files import Policy

CURVE = "evaluations.jsonl"   # a train run's learning curve (agents.rl.training)
CURVE_LIMIT = 64 << 20        # bytes of it read from a source folder


def write_refined(policy: Policy, report: dict[str, Any], out: str | Path | NewPolicyFolder,
                  evaluation: dict[str, Any] | None = None) -> Path:
    """Write the refined ``policy`` as the new policy folder ``out`` (a path, which must not
    exist or be empty, or a :class:`~..artefacts.folders.NewPolicyFolder` the caller holds
    during the refinement): its model zip with the new actor's tensors in ``policy.pth`` (every
    other tensor and entry copied unchanged; the optimizer state is the training's and is not
    used by evaluation), its ``normalization.json`` unchanged, and ``metadata.json`` with
    ``refinement`` (``report``), ``refined_from`` (the source's evaluation and file hashes) and
    ``evaluation``; a train run's ``evaluations.jsonl`` is copied with the refined evaluation
    appended. The source's files are read as a received folder's are (regular files within
    limits, plain entry names). Written at once (staged beside ``out``, verified, renamed into
    place: :func:`~..artefacts.folders.write_policy_folder`): a kill leaves no half folder, and
    a later write removes what a killed one left."""
    import io
    import json
    import zipfile

    import torch

    from microconveyor_env.safe_files import read_bytes, read_text

    from ..artefacts.checkpoint import MODEL, NORMALIZATION
    from ..artefacts.folders import check_new_folder, write_policy_folder
    from ..artefacts.normalization import NORMALIZATION_LIMIT
    from ..artefacts.sb3_files import open_model, read_weights

    if not isinstance(out, NewPolicyFolder):
        check_new_folder(out)   # before reading the source
    src = Path(policy.path)
    zin = open_model(src / MODEL)
    state = read_weights(src / MODEL, "policy.pth", zin)
    fitted = policy.actor.sb3_state()
    missing = sorted(set(fitted) - set(state))
    if missing:
        raise ValueError(f"{str(src / MODEL)!r}: policy.pth has no {missing}")
    state.update(fitted)
    weights = io.BytesIO()
    torch.save(state, weights)
    curve = None
    if (src / CURVE).exists() and evaluation is not None:
        curve = read_text(CURVE, CURVE_LIMIT, src)
    norm = (read_bytes(NORMALIZATION, NORMALIZATION_LIMIT, src)
            if (src / NORMALIZATION).exists() or (src / NORMALIZATION).is_symlink() else None)

    def write_files(tmp: Path) -> dict[str, Any]:
        with zipfile.ZipFile(tmp / MODEL, "w") as zout:
            for name, item in zin.infos.items():
                zout.writestr(item, weights.getvalue() if name == "policy.pth" else zin.read(name))
        if norm is not None:
            (tmp / NORMALIZATION).write_bytes(norm)
        if curve is not None and evaluation is not None:
            # a train run's learning curve, ending with the refined policy's point: the same
            # steps, the training's wall time plus the refinement's (`microconveyor seeds`)
            row = {**evaluation, "steps": policy.metadata.get("steps"), "refined": True,
                   "wall_time_s": float(policy.metadata.get("wall_time_s") or 0.0)
                   + float(report["wall_time_s"])}
            (tmp / CURVE).write_text(curve.rstrip("\n") + "\n" + json.dumps(row) + "\n")
        old = dict(policy.metadata)
        for key in ("note", "evaluation_fresh", "evaluation_provenance", "files"):
            old.pop(key, None)   # they describe the weights before refinement
        return {**old, "refinement": report,
                "refined_from": {"path": str(src), "files": policy.metadata.get("files"),
                                 "evaluation": policy.metadata.get("evaluation")},
                "evaluation": evaluation}

    return write_policy_folder(out, write_files)
