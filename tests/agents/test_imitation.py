"""The DAgger machinery of the learned guidance policy, with TV-LQR as a cheap expert."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("torch")

from rventry_agents.dagger import load_config, load_saved, train_dagger
from rventry_agents.ship import ship
from rventry_agents.imitation import (
    INPUTS,
    N_FEATURES,
    DAggerLaw,
    Horizon,
    LearnedGuidance,
    commands_from_angles,
    tracking_rates,
    expert_angles,
    fit,
    make_network,
    reached_angles,
)
from rventry_env.task import EntryTask
from rventry_env.evaluation.agents import load_agent
from rventry_env.evaluation.rollout import rollout

from dagger_configs import DISTIL, SMALL  # noqa: E402  (tests/agents/ is on the path)


def test_with_beta_one_the_expert_flies_and_every_step_is_labelled():
    expert = load_agent("lqr")
    law = DAggerLaw(load_agent("lqr"), None, beta=1.0, seed=0)
    mixed = rollout(law, seeds=[7], dispersion="standard", record_history=True)
    alone = rollout(expert, seeds=[7], dispersion="standard")
    np.testing.assert_array_equal(mixed.miss_km, alone.miss_km)  # the mixture is the expert itself
    x, y = np.concatenate(law.x), np.concatenate(law.y)
    n = mixed.lengths[0]
    assert x.shape == (n, N_FEATURES) and y.shape == (n, 2) and np.isfinite(x).all()
    # an expert without a plan is labelled with the angles its rates reach: the next step's (the
    # last step ends at the impact, within the step)
    flown = mixed.history_x[1:n, 0, 10:12]
    inside = (flown[:, 0] > 1e-6) & (flown[:, 0] < EntryTask().problem.alpha_max - 1e-6)  # alpha not at a bound
    np.testing.assert_allclose(y[:-1][inside], flown[inside], atol=1e-6)


@pytest.mark.slow
def test_the_replanning_expert_labels_with_its_plans_angles_one_step_ahead():
    """Flying itself, mpc reaches (nearly) its plan's angles in one step; labelling a student that has drifted,
    it gives the plan's angles, not its gentle tracker's next step from the drifted ones."""
    from rventry_env.guidance.replanning import ReplanningGuidance, ReplanningSettings

    # as the shipped students' teachers fly: without the terminal alpha bound, which takes the last
    # step's alpha off the plan on purpose (3 deg here with it on)
    expert = ReplanningGuidance(settings=ReplanningSettings(mesh_intervals=10, replan_s=60.0, terminal_alpha=False))
    law = DAggerLaw(expert, None, beta=1.0, seed=0)
    b = rollout(law, seeds=[7], dispersion="standard", record_history=True)
    y, n = np.concatenate(law.y), b.lengths[0]
    # on a dispersed flight its tracker adds small corrections to the plan's angles
    assert np.degrees(np.abs(y[:-1] - b.history_x[1:n, 0, 10:12])).max() < 0.5
    state = b.history_x[n - 20, :, :].copy()  # within the last plan, which the expert still holds
    t = b.history_t[n - 20]
    on_plan = expert.planned_angles(t, state)
    state[:, 10:12] += np.radians([3.0, 20.0])  # a student 3 deg and 20 deg off
    np.testing.assert_array_equal(expert.planned_angles(t, state), on_plan)
    # a horizon of 3 s is the plan 3 steps on; one per vehicle works alike
    np.testing.assert_array_equal(expert.planned_angles(t, state, 3.0), expert.planned_angles(t + 2.0, state))
    np.testing.assert_array_equal(expert.planned_angles(t, state, np.array([3.0])), expert.planned_angles(t, state, 3.0))
    rates = expert.rates(t, state, expert.estimator.log_scales()) / expert.u_max
    drifted = reached_angles(state, rates, EntryTask())
    assert np.degrees(np.abs(drifted - on_plan)).max() > 2.0  # the tracker's next step keeps most of the drift


def test_a_measurement_without_the_accelerometer_is_refused_by_name():
    from rventry_env.guidance.law import Measurement

    with pytest.raises(ValueError, match=r"sensed_accel_b \(1, 2\)"):
        Measurement.of(np.zeros((1, 26)), np.zeros(1), np.zeros((1, 12)), np.zeros((1, 2)))


def _expert_data(n: int, seed: int):
    """Recorded features, expert angles that depend on the inputs alone, the rates that reach them, and the states."""
    task = EntryTask()
    p = task.problem
    rng = np.random.default_rng(seed)
    x = rng.uniform(-1.0, 1.0, size=(n, N_FEATURES)).astype(np.float32)
    alpha_c = p.alpha_max * (0.5 + 0.3 * np.tanh(x[:, 0] + x[:, 1]))
    sigma_c = 2.0 * np.tanh(x[:, 2] - x[:, 3])
    alpha = alpha_c - rng.uniform(-0.5, 0.5, n) * p.u_alpha_max * task.dt
    sigma = sigma_c - rng.uniform(-0.5, 0.5, n) * p.u_sigma_max * task.dt
    x[:, 11] = 2.0 * alpha / p.alpha_max - 1.0
    x[:, 12], x[:, 13] = np.sin(sigma), np.cos(sigma)
    y = np.stack([(alpha_c - alpha) / (p.u_alpha_max * task.dt), (sigma_c - sigma) / (p.u_sigma_max * task.dt)], 1)
    state = np.zeros((n, 12))
    state[:, 10], state[:, 11] = alpha, sigma
    return task, x, np.stack([alpha_c, sigma_c], 1), y.astype(np.float32), state


def test_commanded_angles_and_the_deadbeat_tracker_invert_each_other():
    task, x, angles, y, state = _expert_data(500, 1)
    np.testing.assert_allclose(reached_angles(state, y, task), angles, atol=1e-6)
    np.testing.assert_allclose(tracking_rates(commands_from_angles(angles, task).astype(float), state, task), y, atol=2e-5)
    np.testing.assert_allclose(expert_angles(object(), np.zeros(500), state, y, task), angles, atol=1e-6)  # no plan
    # with a horizon: the label is where the rates lead by then, and the tracker closes on it at that pace
    ahead = reached_angles(state, y, task, 4.0)
    np.testing.assert_allclose(tracking_rates(commands_from_angles(ahead, task).astype(float), state, task, 4.0), y,
                               atol=2e-5)  # fmt: skip
    with pytest.raises(ValueError, match="the horizon must be at least one control step"):
        LearnedGuidance(make_network((4,)), task=task, horizon=Horizon(0.5, 0.5))


def test_regression_fits_the_expert_commands():
    import torch

    task, x, angles, y, state = _expert_data(6000, 0)
    # the initial weights come from torch's global generator, which the tests run before this one
    # in the same worker have moved, and the reductions' order from the thread count: fix both
    threads = torch.get_num_threads()
    torch.manual_seed(0)
    torch.set_num_threads(1)
    try:
        net = make_network((64, 64))
        losses = fit(net, x, angles, epochs=30, batch_size=256, lr=3e-3, seed=0)
    finally:
        torch.set_num_threads(threads)
    assert losses[-1] < 0.05 * losses[0]  # in units of the commands' spread
    student = LearnedGuidance(net)

    with torch.no_grad():
        commands = net.commands(torch.from_numpy(np.ascontiguousarray(x[:, INPUTS]))).numpy().astype(float)
    rates = tracking_rates(commands, state, task)
    assert student.task == task
    assert np.sqrt(np.mean((rates - y) ** 2)) < 0.1 * y.std()


def test_an_ensemble_student_flies_the_mean_of_its_members_commands():
    import torch

    from rventry_agents.imitation import network_bytes, network_from_bytes

    task, x, angles, y, state = _expert_data(2000, 2)
    net = make_network((16,), members=3)
    fit(net, x, angles, epochs=3, batch_size=256, lr=3e-3, seed=5)
    inputs = torch.from_numpy(np.ascontiguousarray(x[:8, INPUTS]))
    with torch.no_grad():
        each = [m.commands(inputs) for m in net.members]
        assert not torch.allclose(each[0], each[1])  # each member has its own seed
        np.testing.assert_allclose(net.commands(inputs), torch.stack(each).mean(0), rtol=1e-6)
        back = network_from_bytes(network_bytes(net), (16,), members=3)
        np.testing.assert_array_equal(back.commands(inputs), net.commands(inputs))
    with pytest.raises(ValueError, match="at least one member"):
        make_network((16,), members=0)


def test_one_network_distilled_from_an_ensemble_flies_its_commands():
    import torch

    from rventry_agents.imitation import fit_commands, network_commands

    task, x, angles, y, state = _expert_data(2000, 2)
    teacher = make_network((16,), members=3)
    fit(teacher, x, angles, epochs=2, batch_size=256, lr=3e-3, seed=1)  # far from its labels yet
    target = network_commands(teacher, x, batch_size=300)  # in batches: the same as all at once
    with torch.no_grad():
        np.testing.assert_allclose(target, teacher.commands(torch.from_numpy(np.ascontiguousarray(x[:, INPUTS]))).numpy(),
                                   rtol=1e-6, atol=1e-7)  # fmt: skip
    student = make_network((32,), members=1)
    before = np.sqrt(np.mean((network_commands(student, x) - target) ** 2))
    losses = fit_commands(student, x, target, epochs=40, batch_size=256, lr=3e-3, seed=2)
    after = np.sqrt(np.mean((network_commands(student, x) - target) ** 2))
    assert losses[-1] < 0.1 * losses[0] and after < 0.1 * before
    labels = np.sqrt(np.mean((commands_from_angles(angles, task) - target) ** 2))
    assert after < 0.1 * labels  # it flies its teacher's commands, not the labels'


@pytest.mark.slow
def test_a_small_run_writes_a_student_that_evaluate_can_fly(tmp_path):
    cfg = tmp_path / "small.toml"
    cfg.write_text(SMALL)
    out = train_dagger(cfg, tmp_path / "run", workers=1, progress_bar=False)
    rounds = json.loads((out / "rounds.json").read_text())
    assert [r["samples"] for r in rounds] == sorted(r["samples"] for r in rounds)  # data aggregates
    alone = rollout(load_agent("lqr"), seeds=[2_000_000, 2_000_001], dispersion="standard")
    assert rounds[0]["flown_success_rate"] == float(np.mean(alone.is_success))  # round 0: the expert alone
    assert (out / "learning_curve.png").stat().st_size > 5_000
    a = rollout(load_agent(str(out)), seeds=[3, 4], dispersion="standard")
    saved = load_saved(str(out))
    b = rollout(saved, seeds=[3, 4], dispersion="standard")
    np.testing.assert_array_equal(a.miss_km, b.miss_km)
    assert json.loads((out / "student.json").read_text())["load_relief_margin"] == 0.02
    assert saved.relief.margin == 0.02 and [sorted(s) for s in b.law_stats] == [["load_relief_steps"]] * 2
    assert not (out / "distil.json").exists()  # no [distil]: the selected network flies itself
    assert saved.provenance["algorithm"] == "DAgger (supervised imitation of lqr)"  # the config's teacher
    # a longer config resumes: the finished rounds are kept as they are, one more is flown, and
    # the selected network is distilled into one smaller network, which flies instead
    cfg.write_text(SMALL.replace("[fit]", "[[rounds]]\nepisodes = 1\nbeta = 0.0\n[fit]") + DISTIL)
    train_dagger(cfg, out, workers=1, progress_bar=False, resume=True)
    more = json.loads((out / "rounds.json").read_text())
    assert more[:2] == rounds and len(more) == 3 and more[2]["samples"] > rounds[1]["samples"]
    final = json.loads((out / "final.json").read_text())  # the ensemble refitted on all of it
    assert final["members"] == 2 and final["samples"] == more[2]["samples"]
    chosen = json.loads((out / "student.json").read_text())
    best_round = max(more, key=lambda r: (r["select_success_rate"], -r["select_miss_km_mean"]))
    beats = (final["select_success_rate"], -final["select_miss_km_mean"]) > (
        best_round["select_success_rate"], -best_round["select_miss_km_mean"])
    distil = json.loads((out / "distil.json").read_text())
    assert distil["teacher"] == ("final" if beats else best_round["round"])
    assert distil["teacher_members"] == (2 if beats else 1) and distil["samples"] == more[2]["samples"]
    assert 0 < distil["emphasized"] < distil["samples"]  # the states below 20 km, counted three times
    assert (chosen["selected_round"], chosen["distilled_from"]) == ("distilled", distil["teacher"])
    assert (chosen["members"], chosen["hidden"]) == (1, [8])
    # the selected network's tracker: the trained one (one step here) unless the candidate does better
    deploy = json.loads((out / "deploy.json").read_text())
    assert deploy["student"] == chosen["selected_round"]
    trained, candidate = deploy["candidates"]
    assert (trained["tracking_s"], trained["tracking_descent_mps"]) == (1.0, None) and candidate["tracking_s"] == 3.0
    better = (candidate["select_success_rate"], -candidate["select_miss_km_mean"]) > (
        trained["select_success_rate"], -trained["select_miss_km_mean"])
    assert load_saved(str(out)).horizon == (Horizon(3.0, 2.0, 2500.0) if better else Horizon(1.0, 1.0))
    assert ("tracking_s" in chosen) == better and chosen["lookahead_s"] == 1.0
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["selected"]["tracking"] == (candidate if better else trained)
    train_dagger(cfg, out, workers=1, progress_bar=False, resume=True)  # nothing left to do: all taken as it is
    assert json.loads((out / "final.json").read_text()) == final
    assert json.loads((out / "distil.json").read_text()) == distil
    # shipped, the selected student flies the same, with its record
    shipped = ship(out, tmp_path / "shipped")
    assert sorted(p.name for p in shipped.iterdir()) == ["deploy.json", "distil.json", "final.json", "learning_curve.png",
                                                        "metadata.json", "rounds.json", "student.json", "student.pt"]  # fmt: skip
    c = rollout(load_saved(str(shipped)), seeds=[3, 4], dispersion="standard")
    d = rollout(load_saved(str(out)), seeds=[3, 4], dispersion="standard")
    np.testing.assert_array_equal(c.miss_km, d.miss_km)
    assert json.loads((shipped / "metadata.json").read_text())["shipped_from"] == str(out)
    with pytest.raises(FileNotFoundError, match="not a finished DAgger run: missing rounds.json"):
        (tmp_path / "half").mkdir()
        for name in ("student.json", "student.pt"):
            (tmp_path / "half" / name).write_bytes((out / name).read_bytes())
        ship(tmp_path / "half", tmp_path / "x")
    cfg.write_text(SMALL.replace("episodes = 1\nbeta = 0.5", "episodes = 1\nbeta = 0.25"))
    with pytest.raises(ValueError, match="cannot resume"):
        train_dagger(cfg, out, workers=1, progress_bar=False, resume=True)


def test_bad_configs_and_paths_are_named(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(SMALL.replace("episodes = 2\nbeta = 1.0", "episodes = 2\nbeta = 0.5"))
    with pytest.raises(ValueError, match="first round"):
        load_config(bad)
    bad.write_text(SMALL.replace("episodes = 1\nbeta = 0.5", "episodes = 0\nbeta = 0.5"))
    with pytest.raises(ValueError, match=r"\[rounds\]\[1\] episodes must be a whole number >= 1, got 0"):
        load_config(bad)
    with pytest.raises(ValueError, match="not a DAgger run directory"):
        load_saved(str(tmp_path))
    bad.write_text(SMALL.replace("hidden = [16, 16]", "hidden = [16, 16]\nmembers = 0"))
    with pytest.raises(ValueError, match=r"\[student\] members must be a whole number >= 1"):
        load_config(bad)
    bad.write_text(SMALL.replace("tracking = [[3.0, 2.0]]", "tracking = [[3.0]]"))
    with pytest.raises(ValueError, match=r"\[deploy\] tracking must be a list of \[max_s, min_s\] pairs, got \[\[3.0\]\]"):
        load_config(bad)
    bad.write_text(SMALL.replace("tracking = [[3.0, 2.0]]", "tracking = [[2.0, 3.0]]"))
    with pytest.raises(ValueError, match=r"bad.toml: \[deploy\] tracking: a horizon needs 0 < min_s <= max_s"):
        load_config(bad)
    bad.write_text(SMALL.replace("tracking = [[3.0, 2.0]]", "tracking = [[0.5, 0.5]]"))
    with pytest.raises(ValueError, match="the horizon must be at least one control step"):
        train_dagger(bad, tmp_path / "never", workers=1, progress_bar=False)
    assert not (tmp_path / "never" / "rounds.json").exists()
    for good, wrong, message in (
        ("hidden = [8]", "hidden = []", r"\[distil\] hidden must be a list of layer widths .*not empty"),
        ("epochs = 2", "epochs = 0", r"\[distil\] epochs must be a whole number >= 1, got 0"),
        ("emphasis = 3", "emphasis = 0", r"\[distil\] emphasis must be a whole number >= 1, got 0"),
        ("emphasis_below_m = 20_000.0", "emphasis_below_m = -1.0", r"\[distil\] emphasis_below_m must be a finite number >= 0"),
    ):
        bad.write_text(SMALL + DISTIL.replace(good, wrong))
        with pytest.raises(ValueError, match=message):
            load_config(bad)
    bad.write_text(SMALL.replace("load_relief_margin = 0.02", "load_relief_margin = 1.5"))
    with pytest.raises(ValueError, match="load relief margin must lie in"):
        train_dagger(bad, tmp_path / "never", workers=1, progress_bar=False)
    assert not (tmp_path / "never" / "rounds.json").exists()


def test_a_chosen_tracker_flies_in_place_of_the_trained_horizon():
    from rventry_agents.dagger import student_law

    task = EntryTask()
    trained = {"lookahead_s": 4.0, "lookahead_min_s": 2.0, "lookahead_descent_mps": 2500.0, "load_relief_margin": None}
    assert student_law(trained, task)["horizon"] == Horizon(4.0, 2.0, 2500.0)  # the rounds' tracker: the labels'
    chosen = {**trained, "tracking_s": 6.0, "tracking_min_s": 6.0, "tracking_descent_mps": None}
    assert student_law(chosen, task)["horizon"] == Horizon(6.0, 6.0)
    assert student_law({}, task)["horizon"] == Horizon(1.0, 1.0)  # students from before the horizon: one step


def test_the_horizon_shortens_near_the_ground_in_whole_steps():
    h = Horizon(max_s=4.0, min_s=2.0, descent_mps=2500.0)
    radius = 6378137.0
    state = np.zeros((4, 12))
    state[:, 0] = radius + np.array([40e3, 10e3, 7e3, 1e3])
    np.testing.assert_array_equal(h.seconds(state, radius, 1.0), [4.0, 4.0, 3.0, 2.0])
    np.testing.assert_array_equal(Horizon().seconds(state, radius, 1.0), [1.0] * 4)  # the default: one step, deadbeat
    with pytest.raises(ValueError, match="0 < min_s <= max_s"):
        Horizon(max_s=2.0, min_s=3.0)


def test_load_relief_counts_each_episode_flying_not_frozen():
    from rventry_agents.dagger import load_shipped

    shipped = load_shipped("dagger")
    law = LearnedGuidance(shipped.network, horizon=shipped.horizon, load_relief_margin=0.01)
    alone = rollout(law, seeds=[0], dispersion="standard")
    pair = rollout(law, seeds=[0, 7], dispersion="standard")
    assert pair.time_s[1] != pair.time_s[0]  # one copy waits frozen while the other flies on
    steps = [s["load_relief_steps"] for s in pair.law_stats]
    assert alone.law_stats[0]["load_relief_steps"] == steps[0] > 0
    assert np.all(pair.max_load_factor_g <= 12.0)
    bare = rollout(LearnedGuidance(shipped.network, horizon=shipped.horizon), seeds=[0], dispersion="standard")
    assert bare.law_stats == [] and bare.max_load_factor_g[0] > alone.max_load_factor_g[0]


def test_a_saved_network_rebuilds_itself_and_refuses_features_in_another_order():
    import torch

    from rventry_agents.imitation import INPUT_NAMES, network_bytes, network_from_bytes
    from rventry_agents.networks import Ensemble, Student, load_bytes

    net = make_network((8, 4), members=2)
    blob = network_bytes(net)
    back = network_from_bytes(blob)  # no widths, no member count: the bytes carry them
    assert isinstance(back, Ensemble) and back.hidden == (8, 4) and back.n_members == 2
    x = torch.zeros(3, len(INPUT_NAMES))
    with torch.no_grad():
        np.testing.assert_array_equal(back.commands(x), net.commands(x))
    assert isinstance(network_from_bytes(network_bytes(make_network((4,)))), Student)
    with pytest.raises(ValueError, match="hidden = \\(8, 4\\), not the \\(16,\\)"):
        network_from_bytes(blob, (16,))
    swapped = list(INPUT_NAMES)
    swapped[0], swapped[1] = swapped[1], swapped[0]  # a package that builds speed before altitude
    with pytest.raises(ValueError, match="'altitude' \\(index 0 saved, 1 now\\)"):
        load_bytes(blob, tuple(swapped))


def test_the_shipped_student_refuses_a_task_it_was_not_trained_on():
    import math

    from rventry_agents.dagger import load_shipped
    from rventry_env.task import EntryProblem

    assert load_shipped("dagger", EntryTask()).task == EntryTask()
    with pytest.raises(ValueError, match=r"dt: trained 1\.0, here 0\.5.*problem\.alpha_max: trained"):
        load_shipped("dagger", EntryTask(dt=0.5, problem=EntryProblem(alpha_max=math.radians(20.0))))


def test_a_shipped_sb3_policy_refuses_a_task_it_was_not_trained_on():
    from rventry_agents.sb3_policy import load_shipped

    for name in ("ppo", "ppo-residual"):
        with pytest.raises(ValueError, match=r"substeps: trained 1, here 4"):
            load_shipped(name, EntryTask(substeps=4))
    with pytest.raises(ValueError, match=r"no shipped PPO policy named 'ppo-wide'; shipped: ppo, ppo-residual"):
        load_shipped("ppo-wide")


def test_task_records_name_every_difference():
    import json

    from rventry_env.task import EntryProblem

    rec = json.loads(json.dumps(EntryTask().record()))  # through JSON, as a run stores it
    assert EntryTask().differences(rec) == []
    diffs = EntryTask(substeps=2, problem=EntryProblem(q_min=10e3)).differences(rec)
    assert diffs == ["substeps: trained 1, here 2", "problem.q_min: trained 12000.0, here 10000.0"]


@pytest.mark.slow
def test_dagger_on_a_dask_cluster_gives_the_local_run(tmp_path):
    """The expert's episodes flown on a two-worker LocalCluster: the same data, rounds and student."""
    distributed = pytest.importorskip("distributed")
    cfg = tmp_path / "small.toml"
    cfg.write_text(SMALL.replace("[final]\nmembers = 2", "[final]\nmembers = 1"))
    here = train_dagger(cfg, tmp_path / "here", workers=1, progress_bar=False)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cl:
        there = train_dagger(cfg, tmp_path / "there", progress_bar=False, cluster=cl.scheduler_address)
    for k in range(2):
        with np.load(here / f"data_round_{k}.npz") as a, np.load(there / f"data_round_{k}.npz") as b:
            np.testing.assert_array_equal(a["x"], b["x"])
            np.testing.assert_array_equal(a["angles"], b["angles"])
    drop = {"wall_s"}
    ra, rb = (json.loads((d / "rounds.json").read_text()) for d in (here, there))
    assert [{k: v for k, v in r.items() if k not in drop} for r in ra] == [{k: v for k, v in r.items() if k not in drop} for r in rb]
    assert (here / "student.pt").read_bytes() == (there / "student.pt").read_bytes()


def test_an_unknown_shipped_student_is_refused_naming_the_shipped_ones():
    from rventry_agents.dagger import SHIPPED_STUDENTS, load_shipped

    assert set(SHIPPED_STUDENTS) == {"dagger", "dagger-flight"}
    with pytest.raises(ValueError, match=r"no shipped DAgger student is called 'dagger-wide'.*dagger, dagger-flight$"):
        load_shipped("dagger-wide")
