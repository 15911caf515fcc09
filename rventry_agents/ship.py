"""Copy a finished training run's selected policy into the package (``rventry train ship``).

Only what evaluation needs travels, with the run's record:

* a stable-baselines3 run: the best model on the task metric (with its optimizer state dropped:
  Adam's moment buffers are two thirds of the file and no use for inference), its VecNormalize
  statistics, how to fly it (``policy.json``), and the metadata with the exact command, the
  evaluations and the learning curve; by default where :func:`default_destination` puts what
  the run trained (PPO fine-tuning, the PPO residual or a plain baseline);
* a DAgger run (``rventry train dagger``): the selected student (``student.pt`` and
  ``student.json``), ``rounds.json``, ``final.json`` when the run refitted an ensemble,
  ``distil.json`` when it distilled one network, ``deploy.json`` when it chose a tracker, the
  metadata and the learning curve; by default to ``dagger``'s directory;
* a from-scratch run (``rventry train ppo-scratch``) or one of its milestones
  (``milestones/window_<W>s/``): the exported actor (``policy.npz``), its metadata (config and
  provenance) and the run's evaluations and learning curve; by default to ``ppo-scratch``'s
  directory.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from rventry_agents.config import read_json
from rventry_agents.records import PolicyRecord
from rventry_env.util.files import atomic_write, output_set, write_json

RUN_FILES = ("vecnormalize.pkl", "policy.json", "metadata.json", "evaluations.json", "learning_curve.png")
DAGGER_FILES = ("student.pt", "student.json", "rounds.json", "metadata.json", "learning_curve.png")
DAGGER_RECORDS = ("final.json", "distil.json", "deploy.json")  # written by some runs only
OLD_RECORD_NAMES = {"deploy.json": "flight.json"}  # an older run's name of a record, shipped as the new one
JAX_FILES = ("policy.npz", "metadata.json")
JAX_RECORDS = ("evaluations.json", "learning_curve.png")  # the run's: a milestone's are its run folder's


def ship(run_dir: str | Path, dest: str | Path | None = None) -> Path:
    """Copy the selected policy of ``run_dir`` to ``dest`` (default: the packaged policy directory).

    :param run_dir: a finished ``rventry train`` output directory (any stable-baselines3 command,
        ``dagger``, ``ppo-scratch``), or a from-scratch run's milestone folder.
    :param dest: where to put it.
    """
    from rventry_agents.config import algorithm_class
    from rventry_agents.sb3_policy import SB3Policy

    run_dir = Path(run_dir)
    if (run_dir / "student.json").exists():
        return _ship_dagger(run_dir, dest)
    if (run_dir / "policy.npz").exists():
        return _ship_jax(run_dir, dest)
    _check_finished(run_dir, ("model.zip", *RUN_FILES), "training run")
    dest = Path(dest) if dest is not None else default_destination(run_dir)
    SB3Policy(run_dir)  # a policy that does not load (or whose records are corrupt) is not shipped
    algorithm = PolicyRecord.read_json(run_dir / "policy.json").algorithm or "ppo"
    dest.mkdir(parents=True, exist_ok=True)
    model = algorithm_class(algorithm).load(run_dir / "model.zip", device="cpu")
    # a fresh optimizer carries no moment buffers; the weights are untouched (SAC: actor and critic each have one)
    for part in (model.policy, getattr(model, "actor", None), getattr(model, "critic", None)):
        if part is not None and hasattr(part, "optimizer"):
            part.optimizer = part.optimizer_class(part.parameters(), **part.optimizer_kwargs)
    model.save(dest / "model.zip")
    for name in RUN_FILES:
        if name != "metadata.json":
            shutil.copy2(run_dir / name, dest / name)
    _write_metadata(run_dir, dest)
    return dest


def default_destination(run_dir: str | Path) -> Path:
    """Where a finished run's policy is shipped unless told otherwise, by what the run trained: a
    DAgger run's student to ``dagger``'s directory; a stable-baselines3 run where its mode ships
    (:meth:`~rventry_agents.modes.PolicyMode.destination`): PPO fine-tuning of a student to
    ``ppo``'s, a residual on TV-LQR to ``ppo-residual``'s, a plain baseline to its algorithm's
    baseline directory."""
    from rventry_agents.modes import PolicyMode

    run_dir = Path(run_dir)
    if (run_dir / "student.json").exists():
        from rventry_agents.dagger import SHIPPED_DAGGER

        return SHIPPED_DAGGER
    if (run_dir / "policy.npz").exists():
        from rventry_agents.jax_policy import SHIPPED

        return SHIPPED["ppo-scratch"]
    record = PolicyRecord.read_json(run_dir / "policy.json")
    try:
        return PolicyMode.of_record(record).destination(record.algorithm or "ppo")
    except ValueError as exc:
        raise ValueError(f"{run_dir / 'policy.json'}: {exc}") from None


def _check_finished(run_dir: Path, files: tuple[str, ...], what: str) -> None:
    missing = [f for f in files if not (run_dir / f).exists()]
    if missing:
        raise FileNotFoundError(f"{run_dir} is not a finished {what}: missing {', '.join(missing)}")


def _write_metadata(run_dir: Path, dest: Path) -> None:
    """The run's metadata, with where it was shipped from."""
    meta = read_json(run_dir / "metadata.json")
    meta["shipped_from"] = str(run_dir)
    write_json(dest / "metadata.json", meta)


def _ship_jax(run_dir: Path, dest: str | Path | None) -> Path:
    """A from-scratch run's selected actor, or a milestone's, with the run's records."""
    from rventry_agents.jax_policy import JaxPolicy

    dest = Path(dest) if dest is not None else default_destination(run_dir)
    _check_finished(run_dir, JAX_FILES, "from-scratch run or milestone")
    JaxPolicy(run_dir)  # an actor that does not load is not shipped
    run = run_dir.parent.parent if run_dir.parent.name == "milestones" else run_dir
    records = {name: run / name for name in JAX_RECORDS if (run / name).is_file()}
    dest.mkdir(parents=True, exist_ok=True)
    with output_set():  # the actor and its records replaced together
        atomic_write(dest / "policy.npz", (run_dir / "policy.npz").read_bytes())
        for name, path in records.items():
            atomic_write(dest / name, path.read_bytes())
        _write_metadata(run_dir, dest)
    for name in set(JAX_RECORDS) - set(records):
        (dest / name).unlink(missing_ok=True)  # a previous run's record would describe another policy
    return dest


def _ship_dagger(run_dir: Path, dest: str | Path | None) -> Path:
    from rventry_agents.dagger import load_student

    dest = Path(dest) if dest is not None else default_destination(run_dir)
    _check_finished(run_dir, DAGGER_FILES, "DAgger run")
    load_student(run_dir)  # a student that does not load is not shipped
    dest.mkdir(parents=True, exist_ok=True)
    source = {name: run_dir / name for name in (*DAGGER_FILES, *DAGGER_RECORDS)}
    for name, old in OLD_RECORD_NAMES.items():
        if not source[name].exists():
            source[name] = run_dir / old
    for name in DAGGER_RECORDS:
        if not source[name].exists():
            (dest / name).unlink(missing_ok=True)  # a previous run's record would describe another student
    for name, path in source.items():
        if name != "metadata.json" and path.exists():
            atomic_write(dest / name, path.read_bytes())
    _write_metadata(run_dir, dest)
    return dest
