"""Evaluate episodes in parallel: in this process, over a local process pool, or on a Dask cluster.

Episodes are independent. They are cut into *tasks* of consecutive seeds: one episode per
task for a law that declares ``episodes_per_task`` (the re-planning law, whose episodes
cost seconds each), one task holding every episode otherwise (the batched laws, which fly
thousands of episodes per second side by side). The cut depends only on the law and the
seeds, never on where the tasks run, so a run on one process, on ``--workers N`` local
processes or on a Dask cluster gives identical per-episode results for the same seeds.

* ``workers=1``: the tasks run here, one after the other.
* ``workers=N``: a :class:`concurrent.futures.ProcessPoolExecutor` (``spawn`` start, one
  BLAS thread per process).
* ``cluster=ADDRESS``: ``dask.distributed.Client(ADDRESS)``; the workers there need
  rventry installed (``pip install rventry[cluster]``). Dask is imported only for this.

Each process builds a law once and reuses it for all its tasks (building the
re-planning law compiles its NLP, about a second).
"""

from __future__ import annotations

import contextlib
import os
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from rventry_env.task import EntryTask
from rventry_env.evaluation.rollout import EpisodeBatch, rollout


@dataclass(frozen=True)
class EvaluationJob:
    """What every task of an evaluation shares (picklable: it travels to the workers).

    :param agent: an agent name or a saved policy's path (:func:`~rventry_env.evaluation.agents.load_agent`).
    :param dispersion: a dispersion set's name or a dict of :class:`~rventry_env.task.Dispersion` fields.
    :param task: the task.
    :param options: keyword arguments for the built-in law.
    :param record_history: keep every step's state and action.
    :param rung: a rung of the ladder whose start states replace the task's initial state
        (:mod:`rventry_env.evaluation.rungs`; its dispersion and targets are given as usual), or None.
    """

    agent: str
    dispersion: object = "none"
    task: EntryTask = field(default_factory=EntryTask)
    options: tuple = ()  # (name, value) pairs, hashable
    record_history: bool = False
    rung: str | None = None


_LAWS: dict = {}


def cached_law(agent: str, task: EntryTask, options: tuple = ()):
    """The law ``agent`` for ``task`` with ``options`` ((name, value) pairs), built once per
    process: a worker that flies many tasks builds ``mpc``'s transcription once."""
    key = (agent, task, options)
    if key not in _LAWS:
        from rventry_env.evaluation.agents import load_agent

        _LAWS[key] = load_agent(agent, task, **dict(options))
    return _LAWS[key]


def _law(job: EvaluationJob):
    """The law of ``job``, built once per process."""
    return cached_law(job.agent, job.task, job.options)


def run_task(job: EvaluationJob, seeds: list[int]) -> EpisodeBatch:
    """Fly the episodes of one task (a worker's unit of work)."""
    from rventry_env.evaluation.rungs import rung

    return rollout(_law(job), seeds=seeds, dispersion=job.dispersion, task=job.task, record_history=job.record_history,
                   starts=None if job.rung is None else rung(job.rung).starts())  # fmt: skip


def episodes_per_task(job: EvaluationJob, n: int) -> int:
    """How many episodes one task holds: the law's own ``episodes_per_task``, else all of them."""
    return max(1, int(_law(job).episodes_per_task or n))


def split(seeds: list[int], size: int) -> list[list[int]]:
    return [seeds[i : i + size] for i in range(0, len(seeds), size)]


class WorkerLost(RuntimeError):
    """A worker process ended before its task did (killed, or out of memory); nothing was written."""


def _start_worker(parent: int) -> None:
    """Set up a pool worker: one BLAS thread, an end of its own when its parent ends, and Ctrl-C
    left to the parent (which stops the workers itself, see :func:`map_local`)."""
    import signal

    # before the first task's unpickling imports NumPy in this fresh (spawned) process
    os.environ["OMP_NUM_THREADS"] = "1"
    os.environ["OPENBLAS_NUM_THREADS"] = "1"
    # a terminal's Ctrl-C reaches the whole process group: a worker interrupted in its task would
    # report it and take the next one; the parent cancels and stops them all instead
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    end_with_parent(parent)


def _stop_pool(pool, grace_s: float = 2.0) -> None:
    """Stop a process pool now: queued tasks cancelled, running ones ended with their workers
    (SIGTERM, then SIGKILL after ``grace_s``), rather than waiting for every queued task."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for p in processes:
        with contextlib.suppress(Exception):
            p.terminate()
    for p in processes:
        with contextlib.suppress(Exception):
            p.join(grace_s)
            if p.is_alive():
                p.kill()
                p.join(grace_s)


def end_with_parent(parent: int, poll_s: float = 1.0) -> None:
    """End this process when the process ``parent`` ends, however it ends (``kill -9`` included).

    The kernel is asked for a SIGKILL when the parent dies (Linux ``PR_SET_PDEATHSIG``); a daemon
    thread also checks every ``poll_s`` that the parent is still this process's parent, for the
    systems without it and for a parent gone before the request took effect.
    """
    import signal
    import sys
    import threading
    import time

    if sys.platform.startswith("linux"):
        import ctypes

        try:
            ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL))  # PR_SET_PDEATHSIG = 1
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent:
        os._exit(1)

    def watch():
        while True:
            time.sleep(poll_s)
            if os.getppid() != parent:
                os._exit(1)

    threading.Thread(target=watch, name="end-with-parent", daemon=True).start()


def map_local(fn: Callable, calls: list[tuple], workers: int, done: Callable[[int, Any], None]) -> None:
    """Run ``fn(*calls[i])`` for every i: in this process when ``workers`` is 1 (or there is one
    call), else on a pool of up to ``workers`` spawned processes with one BLAS thread each.
    ``done(i, result)`` is called as each finishes, in this process."""
    if workers == 1 or len(calls) <= 1:
        for i, c in enumerate(calls):
            done(i, fn(*c))
        return
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    from concurrent.futures.process import BrokenProcessPool

    ctx = multiprocessing.get_context("spawn")
    # each worker ends with this process: a killed parent leaves no worker behind
    with ProcessPoolExecutor(max_workers=min(workers, len(calls)), mp_context=ctx, initializer=_start_worker,
                             initargs=(os.getpid(),)) as pool:  # fmt: skip
        try:
            futures = {pool.submit(fn, *c): i for i, c in enumerate(calls)}
            for f in as_completed(futures):
                done(futures[f], f.result())
        except BrokenProcessPool:
            _stop_pool(pool)
            raise WorkerLost(
                "a worker process ended before its task did (killed, or out of memory); the other workers "
                "were stopped and nothing was written"
            ) from None
        except BaseException:  # Ctrl-C, or a task that failed: stop now, not after every queued task
            _stop_pool(pool)
            raise


def evaluate(job: EvaluationJob, seeds: list[int], workers: int = 1, cluster: str | None = None,
             progress: Callable[[int], None] | None = None) -> EpisodeBatch:  # fmt: skip
    """Fly one episode per seed; returns them in seed order, however they were spread.

    :param job: the law, dispersion and task.
    :param seeds: one seed per episode.
    :param workers: local processes (1: this one).
    :param cluster: the address of a Dask scheduler (instead of local processes).
    :param progress: called with the number of episodes each finished task held.
    """
    return evaluate_many([(job, seeds)], workers, cluster, None if progress is None else (lambda _j, k: progress(k)))[0]


def evaluate_many(jobs: list[tuple[EvaluationJob, list[int]]], workers: int = 1, cluster: str | None = None,
                  progress: Callable[[int, int], None] | None = None) -> list[EpisodeBatch]:  # fmt: skip
    """:func:`evaluate` for several jobs at once, on one pool (or cluster): the tasks of all of them
    share the workers, so a law that flies in one batched task runs beside another's episodes
    instead of leaving a core idle. Each job's episodes are exactly those :func:`evaluate` gives.

    :param jobs: (job, seeds) pairs.
    :param progress: called with (the job's index, the number of episodes a finished task held).
    """
    if not (isinstance(workers, int) and workers >= 1):
        raise ValueError(f"workers must be a positive integer, got {workers!r}")
    calls, owner = [], []
    for j, (job, seeds) in enumerate(jobs):
        seeds = [int(s) for s in seeds]
        if not seeds:
            raise ValueError("no episodes to evaluate")
        for k, t in enumerate(split(seeds, episodes_per_task(job, len(seeds)))):
            calls.append((job, t))
            owner.append((j, k))
    # the laws that fly an episode per task (the slow ones) first: the batched ones fill in beside them
    order = sorted(range(len(calls)), key=lambda i: len(calls[i][1]))
    calls, owner = [calls[i] for i in order], [owner[i] for i in order]
    results: list[EpisodeBatch | None] = [None] * len(calls)

    def done(i, batch):
        results[i] = batch
        if progress is not None:
            progress(owner[i][0], len(calls[i][1]))

    if cluster is not None:
        map_cluster(run_task, calls, cluster, done,
                    keys=[f"rventry-{job.agent}-{t[0]}-{len(t)}-{i}" for i, (job, t) in enumerate(calls)])  # fmt: skip
    else:
        map_local(run_task, calls, workers, done)
    out = []
    for j in range(len(jobs)):  # each job's tasks back in its seeds' order
        mine = sorted((owner[i][1], i) for i in range(len(calls)) if owner[i][0] == j)
        out.append(concatenate([results[i] for _, i in mine]))
    return out


def map_cluster(fn: Callable, calls: list[tuple], address: str, done: Callable[[int, Any], None],
                keys: list[str] | None = None) -> None:  # fmt: skip
    """:func:`map_local` on a Dask cluster: ``fn(*calls[i])`` for every i on the workers of the
    scheduler at ``address``; ``done(i, result)`` here as each finishes. ``keys`` name the tasks
    (default: the function's name and the call's index).

    :raises ValueError: Dask is not installed, or the scheduler cannot be reached.
    """
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise ValueError("--cluster needs Dask: pip install 'rventry[cluster]'") from None
    try:
        client = Client(address, timeout="20s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise ValueError(f"cannot reach the Dask scheduler at {address}: {exc}") from None
    keys = keys or [f"rventry-{getattr(fn, '__name__', 'task')}-{i}" for i in range(len(calls))]
    futures = []
    try:
        futures = [client.submit(fn, *c, pure=False, key=k) for c, k in zip(calls, keys)]
        index = {f.key: i for i, f in enumerate(futures)}
        for f in as_completed(futures):
            done(index[f.key], f.result())
    except BaseException:  # Ctrl-C, or a task that failed: the cluster's queued and running tasks cancelled
        with contextlib.suppress(Exception):
            client.cancel(futures, force=True)
        raise
    finally:
        client.close()


def map_tasks(fn: Callable, calls: list[tuple], workers: int, done: Callable[[int, Any], None],
              cluster: str | None = None) -> None:  # fmt: skip
    """:func:`map_cluster` when a scheduler address is given, else :func:`map_local`."""
    if cluster is not None:
        map_cluster(fn, calls, cluster, done)
    else:
        map_local(fn, calls, workers, done)


def concatenate(batches: list[EpisodeBatch]) -> EpisodeBatch:
    """One batch from several, episodes in order (histories padded with NaN to the longest)."""
    if len(batches) == 1:
        return batches[0]
    fields_1d = ("miss_km", "vertical_error_deg", "speed_error_mps", "alpha_final_deg", "cost", "max_load_factor_g",
                 "min_dynamic_pressure_pa", "constraint_violation", "is_success", "failure", "time_s")  # fmt: skip
    out = EpisodeBatch(
        **{k: np.concatenate([getattr(b, k) for b in batches]) for k in fields_1d},
        dispersion_draw=np.concatenate([b.dispersion_draw for b in batches]),
        seeds=np.concatenate([b.seeds for b in batches]),
        flight_draw={k: np.concatenate([b.flight_draw[k] for b in batches]) for k in batches[0].flight_draw},
        targets={k: np.concatenate([b.targets[k] for b in batches]) for k in batches[0].targets},
        law_stats=[s for b in batches for s in b.law_stats],
        provenance=batches[0].provenance,
        lengths=np.concatenate([b.lengths for b in batches]),
        navigation=np.concatenate([b.navigation.reshape(-1, 3) for b in batches]),
    )
    if all(b.history_t is not None for b in batches):
        t_max = max(b.history_t.shape[0] for b in batches)

        def pad(a):
            extra = t_max - a.shape[0]
            return np.concatenate([a, np.full((extra, *a.shape[1:]), np.nan)]) if extra else a

        out.history_t = np.concatenate([pad(b.history_t) for b in batches], axis=1)
        out.history_x = np.concatenate([pad(b.history_x) for b in batches], axis=1)
        out.history_a = np.concatenate([pad(b.history_a) for b in batches], axis=1)
    return out


def default_workers() -> int:
    """The local process count by default: every core this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


__all__ = ["WorkerLost", "end_with_parent", "EvaluationJob", "evaluate", "evaluate_many", "map_local", "map_cluster", "map_tasks", "run_task", "concatenate", "split", "default_workers"]
