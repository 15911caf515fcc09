"""Copy a finished training run's selected policy into the package (``rventry train ship``).

Only what evaluation needs travels: the best model on the task metric (with its
optimizer state dropped: Adam's moment buffers are two thirds of the file and no
use for inference), its VecNormalize statistics, how to fly it (``policy.json``),
and the run's record (metadata with the exact command, evaluations, learning curve).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from rventry_env.util.files import write_json

RUN_FILES = ("vecnormalize.pkl", "policy.json", "metadata.json", "evaluations.json", "learning_curve.png")


def ship(run_dir: str | Path, dest: str | Path | None = None) -> Path:
    """Copy the selected policy of ``run_dir`` to ``dest`` (default: the packaged policy directory).

    :param run_dir: a finished ``rventry train ppo | recurrent-ppo | sac`` output directory.
    :param dest: where to put it.
    """
    from rventry_agents.sb3_policy import SHIPPED_PPO
    from rventry_agents.train import algorithm_class

    run_dir = Path(run_dir)
    dest = Path(dest) if dest is not None else SHIPPED_PPO
    missing = [f for f in ("model.zip", *RUN_FILES) if not (run_dir / f).exists()]
    if missing:
        raise FileNotFoundError(f"{run_dir} is not a finished training run: missing {', '.join(missing)}")
    dest.mkdir(parents=True, exist_ok=True)
    algorithm = json.loads((run_dir / "policy.json").read_text()).get("algorithm", "ppo")
    model = algorithm_class(algorithm).load(run_dir / "model.zip", device="cpu")
    # a fresh optimizer carries no moment buffers; the weights are untouched (SAC: actor and critic each have one)
    for part in (model.policy, getattr(model, "actor", None), getattr(model, "critic", None)):
        if part is not None and hasattr(part, "optimizer"):
            part.optimizer = part.optimizer_class(part.parameters(), **part.optimizer_kwargs)
    model.save(dest / "model.zip")
    for name in RUN_FILES:
        shutil.copy2(run_dir / name, dest / name)
    meta = json.loads((dest / "metadata.json").read_text())
    meta["shipped_from"] = str(run_dir)
    write_json(dest / "metadata.json", meta)
    return dest
