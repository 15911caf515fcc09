"""A from-scratch run's records: its output folder, its per-chunk evaluations, its checkpoint and its plot."""

from __future__ import annotations

import json
import shutil
import sys
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from rventry_agents.config import ConfigError
from rventry_env.util.files import atomic_write, save_figure, write_json

CHECKPOINT = "checkpoint"
# the run's state at its selected chunk (the one its policy.npz was exported from): a checkpoint and
# the run's config, so that ``--init-from RUN/selected`` goes on from the selected policy with its own
# critic, optimizer moments and reward statistics
SELECTED = "selected"
# windows (s before impact) whose success is recorded after each chunk: where along the flight the policy lands from
PROBES = ((30.0, 60.0), (150.0, 200.0), (450.0, 550.0))


def check_out(out: Path, cfg, resume: bool) -> None:
    """Refuse an output that cannot hold this run, before anything is written or compiled."""
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out} is a file; give a directory for the run")
    started = (out / "config.json").is_file()
    if resume:
        if not (out / CHECKPOINT / "state.json").is_file():
            raise ValueError(f"cannot resume {out}: it has no {CHECKPOINT}/ (a run writes one after each chunk)")
        recorded = _resumable(json.loads((out / "config.json").read_text())) if started else {}
        now = _resumable(json.loads(json.dumps(cfg.to_dict())))
        if recorded != now:
            diff = sorted(k for k in set(now) | set(recorded) if recorded.get(k) != now.get(k))
            raise ValueError(f"cannot resume {out}: the config differs from the one it started with (sections {diff}); "
                             "only the budget ([train] total_timesteps, max_wall_s) may change")  # fmt: skip
    elif started:
        raise ValueError(f"{out} already holds a run; give another --out, or --resume to go on with it")
    out.mkdir(parents=True, exist_ok=True)


def check_source(source: Path, out: Path) -> Path:
    """The folder another run starts from (``init_from``), refused before anything is compiled
    unless it holds a checkpoint or an exported policy and is not the new run's own folder."""
    if not (source / CHECKPOINT / "state.json").is_file() and not PolicyStart.holds(source):
        raise ValueError(f"cannot start from {source}: it holds no {CHECKPOINT}/ (a from-scratch run writes one after "
                         "each chunk) and no policy.npz with its metadata.json (a run's selected policy, or a "
                         "shipped one)")  # fmt: skip
    if source.resolve() == out.resolve():
        raise ValueError(f"--init-from {source} is the new run's own --out; give a new --out, or --resume to go on "
                         "with that run")  # fmt: skip
    return source


def read_start(source: Path):
    """Where a run starts from: the :class:`Checkpoint` in ``source``, or else its exported policy
    (:class:`PolicyStart`)."""
    return Checkpoint.read(source) if (source / CHECKPOINT / "state.json").is_file() else PolicyStart.read(source)


def _resumable(config: dict) -> dict:
    """What a resumed run must share with the run it resumes: all but the budget."""
    train = {k: v for k, v in config.get("train", {}).items() if k not in ("total_timesteps", "max_wall_s")}
    return {**config, "train": train}


def record_chunk(trainer, ts, steps: int, wall_s: float, chunk_s: float) -> dict:
    """After a chunk: move the curriculum, fly the selection set; the chunk's record."""
    import jax

    rec = {"timesteps": steps, "wall_s": wall_s, "chunk_s": chunk_s,
           "exploration_std": np.exp(np.asarray(ts.actor_ts.params["params"]["action_log_std"])).tolist()}  # fmt: skip
    c = trainer.curriculum
    if c.c.kind == "reverse":
        front = trainer.frontier(ts, jax.random.PRNGKey(steps))
        window = c.window
        moved = c.advance(front["success_rate"])
        if moved:
            trainer.with_window()
        rec["curriculum"] = {"window_s": window, "frontier_success": front["success_rate"], "frontier": front,
                             "next_window_s": c.window}  # fmt: skip
    rec["select"] = trainer.select(ts)
    rec["probes"] = {f"{lo:g}-{hi:g}": trainer.probe(ts, lo, hi, jax.random.PRNGKey(steps + 1))["success_rate"]
                     for lo, hi in PROBES}  # fmt: skip
    return rec


class Processes:
    """The processes that trained a run: those the checkpoint it resumes names, then this one, each
    as its first and last step with its command, commit, machine and packages
    (:class:`~rventry_env.util.provenance.RunRecord`). Two runs of one config retrace each other to
    the bit on one machine and one thread count; on two, XLA may compile other instructions and
    float32 training parts within a chunk, so a run's record says where each of its steps was
    trained."""

    def __init__(self, before: list, first_step: int):
        from rventry_env.util.provenance import RunRecord

        self.before, self.first, self.record = list(before), int(first_step), RunRecord(sys.argv)
        self._at: tuple[int, list[dict]] | None = None

    def now(self, last_step: int) -> list[dict]:
        """The processes through ``last_step``: this one's entry is taken once a step, so the
        checkpoint and the metadata written at one step say the same."""
        if self._at is None or self._at[0] != last_step:
            self._at = (last_step, [*self.before, {"timesteps": [self.first, int(last_step)], **self.record.provenance()}])
        return self._at[1]


AVERAGE = "average.msgpack"  # in the checkpoint: the actor's parameters averaged over chunks ([train] policy_average)


class Checkpoint:
    """``checkpoint/``: the training state (flax's msgpack), the curriculum's window and the history,
    the average of the actor's parameters where the run keeps one, and the processes that trained
    it (``runs``: each one's first and last step, its commit, machine and packages; a resumed run
    adds its own to those it resumes), written whole after each chunk (a new folder renamed over
    the old)."""

    def __init__(self, out: Path, window: float, history: list, wall_s: float, steps: int, init_from: dict | None = None,
                 runs: list | None = None):  # fmt: skip
        self.out, self.window, self.history, self.wall_s, self.steps = out, window, history, wall_s, steps
        self.other_vehicles = False  # whether restore started every vehicle afresh (a rung of another form)
        self.init_from = init_from  # where the run that wrote it started, if from another run's checkpoint
        self.runs = list(runs or [])  # the processes that trained it, each with its steps, machine and code

    def origin(self) -> dict:
        """This checkpoint as the start of another run: its folder, steps, window and wall time (and its own start)."""
        out = {"run": str(self.out), "timesteps": self.steps, "window_s": self.window, "wall_s": self.wall_s}
        return out if self.init_from is None else {**out, "init_from": self.init_from}

    @staticmethod
    def write(out: Path, ts, window: float, history: list, wall_s: float, steps: int, init_from: dict | None = None,
              average=None, runs: list | None = None) -> None:  # fmt: skip
        from flax import serialization

        with _written_whole(out / CHECKPOINT) as tmp:
            tmp.mkdir(parents=True)
            atomic_write(tmp / "train_state.msgpack", serialization.to_bytes(ts))
            if average is not None:
                atomic_write(tmp / AVERAGE, serialization.to_bytes(average))
            state = {"window_s": window, "wall_s": wall_s, "timesteps": steps, "history": history}
            state = state if init_from is None else {**state, "init_from": init_from}
            write_json(tmp / "state.json", state if runs is None else {**state, "runs": runs})

    @staticmethod
    def keep_selected(out: Path) -> Path:
        """Copy the checkpoint just written, with the run's ``config.json``, to ``out/selected/`` (a
        new folder renamed over the old): the state of the chunk whose policy the run has just
        exported. Returns the folder."""
        with _written_whole(out / SELECTED) as tmp:
            shutil.copytree(out / CHECKPOINT, tmp / CHECKPOINT)
            shutil.copy2(out / "config.json", tmp / "config.json")
        return out / SELECTED

    @classmethod
    def read(cls, out: Path) -> Checkpoint:
        path = out / CHECKPOINT / "state.json"
        try:
            s = json.loads(path.read_text())
            return cls(out, float(s["window_s"]), list(s["history"]), float(s["wall_s"]), int(s["timesteps"]),
                       s.get("init_from"), s.get("runs"))  # fmt: skip
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise ConfigError(f"cannot start from {out}: {path} is not a checkpoint ({type(exc).__name__}: {exc})") from None

    def restore(self, template):
        """(training state, history, wall time, steps) from the checkpoint; ``template`` a fresh
        training state of the config that goes on (its structure and every array's shape)."""
        from flax import serialization

        path = self.out / CHECKPOINT / "train_state.msgpack"
        try:
            saved = _renamed(serialization.msgpack_restore(path.read_bytes()))
            want = serialization.to_state_dict(template)
            # vehicles of another rung whose state has another form (the flight-grade errors): the
            # template's fresh vehicles stand in for them, as fresh_vehicles puts them below
            self.other_vehicles = isinstance(saved, dict) and _form(saved.get("env_state")) != _form(want["env_state"])
            if self.other_vehicles:
                saved = {**saved, **{k: want[k] for k in VEHICLES}}
            ts = serialization.from_state_dict(template, saved)
            if self.other_vehicles:
                ts = fresh_vehicles(ts, template)
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise ConfigError(f"cannot start from {self.out}: {path} does not hold this config's training state "
                              f"({type(exc).__name__}: {exc})") from None  # fmt: skip
        if misfit := _misfit(template, ts):
            where, have, want = misfit
            raise ConfigError(f"cannot start from {self.out}: its training state does not fit this config: "
                              f"{where} has shape {have} there and {want} here (the network, num_envs and the "
                              "algorithm's sizes must match)")  # fmt: skip
        return ts, self.history, self.wall_s, self.steps

    def average(self, template):
        """The average of the actor's parameters the checkpoint holds (None where it holds none);
        ``template`` the actor's parameters, for their structure."""
        from flax import serialization

        path = self.out / CHECKPOINT / AVERAGE
        if not path.is_file():
            return None
        try:
            average = serialization.from_bytes(template, path.read_bytes())
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise ConfigError(f"cannot start from {self.out}: {path} is not an average of this config's actor "
                              f"({type(exc).__name__}: {exc})") from None  # fmt: skip
        if misfit := _misfit(template, average):
            where, have, want = misfit
            raise ConfigError(f"cannot start from {self.out}: its averaged actor's {where} has shape {have} and this "
                              f"config's {want}")  # fmt: skip
        return average


@contextmanager
def _written_whole(final: Path):
    """A folder written whole: the block writes it at the path this yields (``final`` with ``.tmp``),
    which then takes ``final``'s place (the one before kept aside as ``.old`` until the new one is in);
    a block that raises leaves ``final`` as it was."""
    tmp, old = final.with_name(f"{final.name}.tmp"), final.with_name(f"{final.name}.old")
    shutil.rmtree(tmp, ignore_errors=True)
    yield tmp
    shutil.rmtree(old, ignore_errors=True)
    if final.exists():
        final.rename(old)
    tmp.rename(final)
    shutil.rmtree(old, ignore_errors=True)


def _misfit(template, tree):
    """The first array of ``tree`` whose shape is not its place's in ``template``, as (where, its shape,
    the template's); None where every shape fits."""
    import jax

    for (where, want), have in zip(jax.tree_util.tree_flatten_with_path(template)[0], jax.tree_util.tree_leaves(tree)):
        if np.shape(want) != np.shape(have):
            return jax.tree_util.keystr(where), np.shape(have), np.shape(want)
    return None


class PolicyStart:
    """An exported policy (``policy.npz`` and its ``metadata.json``: a run's selected policy, or a
    shipped one) as the start of a run: its actor and its observation statistics, in a training
    state whose critic, optimizers and reward statistics are new (the export holds none of them).
    Its steps, wall time and curriculum window are what its metadata gives: a run's export, the
    whole run's (what the policy cost, the chunks trained after the selected one included) and its
    last window; a milestone's, where it was kept. A run from it starts with an empty history. A
    new critic steers the first updates with values it has not learned: ``[ppo] train_actor =
    false`` for the first chunks holds the policy while it learns."""

    def __init__(self, out: Path, arrays: dict, meta: dict):
        self.out, self.arrays, self.meta = out, arrays, meta
        self.steps = int(meta["timesteps"])
        self.wall_s = float(meta["wall_s"])
        self.window = float(meta["final_window_s"] if "final_window_s" in meta else meta["window_s"])
        self.init_from = meta.get("provenance", {}).get("init_from")

    @staticmethod
    def holds(folder: Path) -> bool:
        return (folder / "policy.npz").is_file() and (folder / "metadata.json").is_file()

    @classmethod
    def read(cls, folder: Path) -> PolicyStart:
        if not cls.holds(folder):
            raise ConfigError(f"cannot start from {folder}: it holds neither a {CHECKPOINT}/ nor a policy.npz with its "
                              "metadata.json")  # fmt: skip
        try:
            meta = json.loads((folder / "metadata.json").read_text())
            with np.load(folder / "policy.npz") as f:
                arrays = {k: f[k] for k in f.files}
            return cls(folder, arrays, meta)
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise ConfigError(f"cannot start from {folder}: its policy.npz or metadata.json is not an exported policy "
                              f"({type(exc).__name__}: {exc})") from None  # fmt: skip

    def origin(self) -> dict:
        """This policy as the start of another run: its folder, the run it was selected in, steps, window and wall time."""
        p = self.meta.get("provenance", {})
        out = {"policy": str(self.out), "timesteps": self.steps, "window_s": self.window, "wall_s": self.wall_s}
        if self.meta.get("shipped_from"):
            out["run"] = self.meta["shipped_from"]
        if "selected_at_timesteps" in p:
            out["selected_at_timesteps"] = int(p["selected_at_timesteps"])
        return out if self.init_from is None else {**out, "init_from": self.init_from}

    def average(self, template) -> None:
        """An export holds no average of the actor's parameters."""
        return None

    def check(self, cfg) -> None:
        """Refuse a config the policy cannot go on under: other actions, activation or command time."""
        a = self.arrays
        got = {"[env] actions": str(a["actions"]), "[ppo] activation": str(a["activation"]),
               "[env] command_time_s": float(a["command_time_s"])}  # fmt: skip
        want = {"[env] actions": cfg.env.actions, "[ppo] activation": cfg.ppo.activation,
                "[env] command_time_s": float(cfg.env.command_time_s)}  # fmt: skip
        for key, value in want.items():
            if got[key] != value:
                raise ConfigError(f"cannot start from {self.out}: its policy has {key} = {got[key]!r} and this config "
                                  f"{value!r}")  # fmt: skip

    def restore(self, template):
        """(training state, history, wall time, steps): ``template`` (a new training state of this
        config) with the policy's actor, observation statistics and step count."""
        import jax.numpy as jnp

        a = self.arrays
        actor = template.actor_ts.params["params"]
        hidden = actor["features"]
        n = sum(k.startswith("kernel_") for k in a)
        if n != len(hidden):
            raise ConfigError(f"cannot start from {self.out}: its policy has {n} hidden layers and this config's "
                              f"network {len(hidden)}")  # fmt: skip
        layers = {f"Dense_{i}": {"kernel": a[f"kernel_{i}"], "bias": a[f"bias_{i}"]} for i in range(n)}
        new = {"features": layers, "action_mean": {"kernel": a["mean_kernel"], "bias": a["mean_bias"]},
               "action_log_std": a["log_std"]}  # fmt: skip
        params = {**template.actor_ts.params, "params": _like(actor, new, self.out)}
        step = jnp.asarray(self.steps, jnp.asarray(template.global_step).dtype)
        ts = template.replace(actor_ts=template.actor_ts.replace(params=params), global_step=step)
        rms = getattr(ts, "obs_rms_state", None)
        if rms is not None:
            mean, var = (jnp.asarray(a[k], rms.mean.dtype) for k in ("obs_mean", "obs_var"))
            if mean.shape != rms.mean.shape:
                raise ConfigError(f"cannot start from {self.out}: its policy sees {mean.shape[0]} features and this "
                                  f"environment {rms.mean.shape[0]}")  # fmt: skip
            # counted as the steps that made them: the statistics the actor was trained under barely move
            count = jnp.asarray(float(self.steps), rms.mean.dtype)
            ts = ts.replace(obs_rms_state=rms.replace(mean=mean, var=var, count=count))
        return ts, [], self.wall_s, self.steps


def _like(template: dict, new: dict, source: Path, where: str = "") -> dict:
    """``new``'s arrays in ``template``'s tree, each of its shape and dtype (refused, naming the array, where not)."""
    import jax.numpy as jnp

    out = {}
    for key, want in template.items():
        if isinstance(want, dict):
            out[key] = _like(want, new[key], source, f"{where}{key}.")
            continue
        have = np.asarray(new[key])
        if have.shape != np.shape(want):
            raise ConfigError(f"cannot start from {source}: its policy's {where}{key} has shape {have.shape} and this config's "
                              f"network {np.shape(want)} (the network must match)")  # fmt: skip
        out[key] = jnp.asarray(have, jnp.asarray(want).dtype)
    return out


# the parts of a training state that are the vehicles in flight (rejax's PPO state)
VEHICLES = ("env_state", "last_obs", "last_done")


def fresh_vehicles(ts, fresh):
    """The training state ``ts`` with every vehicle started afresh as in ``fresh`` (a new training
    state of the config that goes on): the environments' states, their last observations and done
    flags, and the reward statistics' running returns of the episodes cut off; the networks, the
    optimizers, the observation and reward statistics and the random key as they were. What a
    stage or a run on another rung starts from: the vehicles in flight were drawn on the rung
    before, and on the flight-grade rung their state has another form (its sensor and navigation
    errors)."""
    out = ts.replace(**{k: getattr(fresh, k) for k in VEHICLES})
    rms = getattr(ts, "rew_rms_state", None)
    if rms is not None and hasattr(rms, "returns"):
        out = out.replace(rew_rms_state=rms.replace(returns=fresh.rew_rms_state.returns))
    return out


def _form(tree):
    """The nesting of a saved state's dicts, without the arrays (None where a part is absent)."""
    if isinstance(tree, dict):
        return {k: _form(v) for k, v in tree.items()}
    return None if tree is None else ()


def _renamed(tree):
    """A saved training state with the environment state's field ``flight`` (its name in
    checkpoints written before it became ``episode``, :class:`~rventry_env.envs.functional.EnvState`)
    under its current name."""
    if not isinstance(tree, dict):
        return tree
    out = {k: _renamed(v) for k, v in tree.items()}
    if "flight" in out and "episode" not in out and "scales" in out:
        out["episode"] = out.pop("flight")
    return out


def plot_learning_curve(history: list[dict], path: Path, title: str) -> Path | None:
    """Success rate and median miss of the selection set, and the curriculum's window, against steps."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from rventry_env.util.files import plain_log_labels

    if not history:
        return None
    steps = np.array([h["timesteps"] for h in history]) / 1e6
    sel = [h["select"] for h in history]
    fig, ax = plt.subplots(1, 3, figsize=(13, 3.6))
    ax[0].plot(steps, [s["success_rate"] for s in sel], "o-", ms=3, label="success")
    ax[0].plot(steps, [s["miss_within_rate"] for s in sel], "-", lw=1, label="miss <= 5 km")
    ax[0].plot(steps, [s["vertical_within_rate"] for s in sel], "-", lw=1, label="vertical <= 5 deg")
    if any("average" in h for h in history):  # [train] policy_average: the averaged actor's flight as well
        ax[0].plot(steps, [h["average"]["select"]["success_rate"] if "average" in h else np.nan for h in history],
                   "s--", ms=3, lw=1, label="success, averaged actor")  # fmt: skip
    ax[0].set(xlabel="environment steps (M)", ylabel="share of selection episodes", ylim=(-0.02, 1.02))
    ax[0].legend(fontsize=7, loc="upper left")
    ax[1].semilogy(steps, [max(s["miss_km_p50"], 1e-2) for s in sel], "o-", ms=3)
    ax[1].set(xlabel="environment steps (M)", ylabel="median miss (km)")
    plain_log_labels(ax[1])
    windows = [h.get("curriculum", {}).get("window_s") for h in history]
    if any(w is not None for w in windows):
        ax[2].plot(steps, [np.nan if w is None else w for w in windows], "o-", ms=3)
        ax[2].set(xlabel="environment steps (M)", ylabel="curriculum window (s before impact)")
    else:
        ax[2].plot(steps, [h["exploration_std"][0] for h in history], "o-", ms=3, label="alpha")
        ax[2].plot(steps, [h["exploration_std"][1] for h in history], "o-", ms=3, label="bank")
        ax[2].set(xlabel="environment steps (M)", ylabel="exploration std")
        ax[2].legend(fontsize=7)
    for a in ax:
        a.grid(alpha=0.3)
    n = sel[-1]["episodes"]
    fig.suptitle(f"{title}: deterministic policy on {n} selection episodes after each chunk")
    return save_figure(fig, path)


__all__ = [
    "CHECKPOINT",
    "Checkpoint",
    "PolicyStart",
    "check_out",
    "check_source",
    "plot_learning_curve",
    "read_start",
    "record_chunk",
]
