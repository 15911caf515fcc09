"""The phases of a DAgger run (rventry_agents/dagger.py), each alone, and the run's reproducibility."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("torch")

from rventry_agents.dagger import (
    RunClock,
    Rounds,
    Selected,
    check_resumable,
    choose_deployment,
    distil_selected,
    load_student,
    new_network,
    prepare_run,
    refit_ensemble,
    train_dagger,
    write_run_record,
)
from rventry_agents.imitation import N_FEATURES, network_bytes

from dagger_configs import DISTIL  # noqa: E402  (tests/agents/ is on the path)
from dagger_configs import SMALL as _SMALL  # noqa: E402

SMALL = _SMALL.replace("[select]\nepisodes = 3", "[select]\nepisodes = 2")  # one selection episode fewer


def _run(tmp_path, text=SMALL, seed=None, name="run"):
    cfg = tmp_path / f"{name}.toml"
    cfg.write_text(text)
    return prepare_run(cfg, tmp_path / name, workers=1, seed=seed)


def _rounds(run, n=600, seed=0) -> Rounds:
    """Two rounds of recorded features and labels (synthetic, of the recorded shapes), the first selected."""
    rng = np.random.default_rng(seed)
    rounds = Rounds()
    for k in range(2):
        rounds.xs.append(rng.uniform(-1, 1, (n, N_FEATURES)).astype(np.float32))
        rounds.ys.append(rng.uniform(0.0, 0.4, (n, 2)).astype(np.float32))
        rounds.records.append({"round": k, "samples": n * (k + 1), "select_success_rate": 0.0,
                               "select_miss_km_mean": 1e3 + k, "select_miss_km_p50": 1e3, "flown_success_rate": 0.0})  # fmt: skip
    net = new_network(run.hidden, run.members, run.fit_seed, "round 0")
    rounds.best = Selected(0, network_bytes(net), run.members, run.hidden)
    return rounds


def test_new_networks_start_from_the_runs_seed_and_stage():
    import torch

    a, b = new_network((8,), 1, 0, "round 2"), new_network((8,), 1, 0, "round 2")
    torch.rand(100)  # whatever else drew from the global generator in between
    c = new_network((8,), 1, 0, "round 2")
    d, e = new_network((8,), 1, 0, "round 3"), new_network((8,), 1, 1, "round 2")
    same = [torch.equal(p, q) for p, q in zip(a.state_dict().values(), b.state_dict().values())]
    assert all(same) and network_bytes(a) == network_bytes(c)
    assert network_bytes(a) != network_bytes(d) and network_bytes(a) != network_bytes(e)


def test_prepare_run_reads_the_settings_the_phases_use(tmp_path):
    run = _run(tmp_path, seed=3)
    assert run.hidden == (16, 16) and run.members == 1 and run.expert == "lqr" and run.expert_settings == ()
    assert run.fit_seed == 3 and run.first_seed == 2_000_000 + 3_000
    assert run.fit_settings() == {"epochs": 3, "batch_size": 512, "lr": 1e-3, "seed": 3, "weight_decay": 0.0}
    assert run.law["load_relief_margin"] == 0.02 and [h.max_s for h in run.trackers] == [3.0]


def test_expert_settings_apply_on_top_of_the_named_experts_preset(tmp_path):
    from rventry_agents.imitation import expert_options
    from rventry_env.guidance.replanning import ReplanningSettings

    assert expert_options("mpc-flight") == () and expert_options("lqr") == ()
    (_, flight), = expert_options("mpc-flight", (("final_replan_s", 5.0), ("freeze_s", 5.0)))
    preset = ReplanningSettings.flight_grade()
    assert (flight.final_replan_s, flight.freeze_s) == (5.0, 5.0)
    assert (flight.load_relief_margin, flight.density_bands) == (preset.load_relief_margin, preset.density_bands)
    (_, plain), = expert_options("mpc", (("q_margin", 0.08),))
    assert plain == ReplanningSettings(q_margin=0.08) and plain.load_relief_margin is None
    with pytest.raises(ValueError, match=r"\['q_margin'\] apply to the re-planning experts .* not 'lqr'"):
        expert_options("lqr", (("q_margin", 0.1),))
    # a config that gives settings to an expert without them fails before anything flies
    with pytest.raises(ValueError, match="not 'lqr'"):
        _run(tmp_path, SMALL.replace('agent = "lqr"', 'agent = "lqr"\nq_margin = 0.1'))


def test_a_resume_with_another_config_is_refused_naming_the_fields(tmp_path):
    check_resumable(_run(tmp_path), resume=False)
    assert json.loads((tmp_path / "run" / "run.json").read_text())["student"]["hidden"] == [16, 16]
    check_resumable(_run(tmp_path), resume=True)  # the same config: accepted
    # a longer run, a distillation or another tracker scan may be added on resume
    check_resumable(_run(tmp_path, SMALL.replace("[fit]", "[[rounds]]\nepisodes = 1\nbeta = 0.0\n[fit]") + DISTIL),
                    resume=True)  # fmt: skip
    cases = {
        "seed": (SMALL, 5, "seed (null -> 5)"),
        "width": (SMALL.replace("hidden = [16, 16]", "hidden = [32]"), None, "student.hidden ([16, 16] -> [32])"),
        "dispersion": (SMALL.replace('dispersion = "standard"\ntrain', 'dispersion = "wide"\ntrain'), None,
                       'data.dispersion ("standard" -> "wide")'),
        "margins": (SMALL.replace('agent = "lqr"', 'agent = "mpc"\nq_margin = 0.1'), None, "expert.q_margin (null -> 0.1)"),
    }  # fmt: skip
    for name, (text, seed, needle) in cases.items():
        with pytest.raises(ValueError, match="cannot resume .*another config") as err:
            check_resumable(_run(tmp_path, text, seed), resume=True)
        assert needle in str(err.value), name
    # a run from before run.json was kept: checked against its metadata
    (tmp_path / "run" / "run.json").unlink()
    (tmp_path / "run" / "metadata.json").write_text(json.dumps({"seed": 0, "config": _run(tmp_path).cfg.to_dict()}))
    with pytest.raises(ValueError, match=r"fit.seed \(0 -> 4\)"):
        check_resumable(_run(tmp_path, seed=4), resume=True)


def test_the_ensemble_refit_is_selected_only_when_it_beats_the_best_round(tmp_path):
    run = _run(tmp_path)
    run.out.mkdir(exist_ok=True)  # prepare_run made it
    rounds = _rounds(run)
    best, final = refit_ensemble(run, rounds, RunClock(), resume=False)
    assert final["members"] == 2 and final["samples"] == 1200
    stored = json.loads((run.out / "final.json").read_text())
    assert stored["fit_loss_last"] == final["fit_loss_last"]
    beats = (final["select_success_rate"], -final["select_miss_km_mean"]) > (0.0, -1e3)
    assert (best.source == "final") == beats
    # on resume an ensemble of the same size and data is taken as it is
    again, taken = refit_ensemble(run, rounds, RunClock(), resume=True)
    assert taken == final and again == best
    # none asked for: an earlier run's record goes
    none = _run(tmp_path, SMALL.replace("members = 2", "members = 1"))
    assert refit_ensemble(none, rounds, RunClock(), resume=False) == (rounds.best, None)
    assert not (run.out / "final.json").exists()


def test_the_distilled_network_flies_in_place_of_its_teacher(tmp_path):
    run = _run(tmp_path, SMALL + DISTIL)
    run.out.mkdir(exist_ok=True)  # prepare_run made it
    rounds = _rounds(run)
    best, rec = distil_selected(run, rounds, rounds.best, RunClock(), resume=False)
    assert best.source == "distilled" and (best.members, best.hidden) == (1, (8,))
    assert rec["teacher"] == 0 and rec["samples"] == 1200
    student = json.loads((run.out / "student.json").read_text())
    assert student["selected_round"] == "distilled" and student["distilled_from"] == 0
    assert (run.out / "student.pt").read_bytes() == best.weights
    plain = _run(tmp_path)
    assert distil_selected(plain, rounds, rounds.best, RunClock(), resume=False) == (rounds.best, None)
    assert not (run.out / "distil.json").exists()


def test_a_lost_round_network_is_fitted_again_and_checked_against_its_record(tmp_path):
    import hashlib

    from rventry_agents.dagger import _round_network

    run = _run(tmp_path)
    run.out.mkdir(exist_ok=True)  # prepare_run made it
    rounds = _rounds(run)
    path = run.out / "student_round_1.pt"
    blob = _round_network(run, 1, rounds)  # no file, no recorded hash (a run of before): fitted and saved
    assert path.read_bytes() == blob and _round_network(run, 1, rounds) == blob  # then read, not fitted
    path.unlink()
    rounds.records[1]["network_sha256"] = hashlib.sha256(blob).hexdigest()
    assert _round_network(run, 1, rounds) == blob  # the seed and data give the recorded network again
    path.unlink()
    rounds.records[1]["network_sha256"] = "0" * 64
    with pytest.raises(ValueError, match=r"student_round_1.pt is missing, and fitting it again .* another network"):
        _round_network(run, 1, rounds)
    assert not path.exists()  # nothing written that the record disowns
    rounds.records[0]["network_sha256"] = "0" * 64  # round 1's fit uses rounds 0 and 1's data, not round 0's hash
    path.unlink(missing_ok=True)
    rounds.records[1]["network_sha256"] = hashlib.sha256(blob).hexdigest()
    assert _round_network(run, 1, rounds) == blob


def test_a_network_distilled_at_its_teachers_widths_flies_only_if_it_does_as_well(tmp_path):
    same_width = SMALL + DISTIL.replace("hidden = [8]", "hidden = [16, 16]")
    plain = _run(tmp_path, same_width, name="plain")
    plain.out.mkdir(exist_ok=True)
    rounds = _rounds(plain)
    rounds.records[0]["select_success_rate"] = 1.0  # a teacher no distilled network of 2 episodes beats
    assert distil_selected(plain, rounds, rounds.best, RunClock(), resume=False)[0].source == "distilled"  # the default
    run = _run(tmp_path, same_width + "keep_teacher_if_better = true\n")
    run.out.mkdir(exist_ok=True)  # prepare_run made it
    best, rec = distil_selected(run, rounds, rounds.best, RunClock(), resume=False)
    assert best == rounds.best and rec is None
    assert json.loads((run.out / "distil.json").read_text())["flies"] is False  # measured, recorded, not flown
    student = json.loads((run.out / "student.json").read_text())
    assert student["selected_round"] == 0 and "distilled_from" not in student
    assert (run.out / "student.pt").read_bytes() == rounds.best.weights
    rounds.records[0]["select_success_rate"] = -1.0  # a teacher any distilled network beats
    best, rec = distil_selected(run, rounds, rounds.best, RunClock(), resume=True)
    assert best.source == "distilled" and rec["teacher"] == 0
    with pytest.raises(ValueError, match=r"\[distil\] keep_teacher_if_better must be true or false, got 'yes'"):
        _run(tmp_path, same_width + 'keep_teacher_if_better = "yes"\n')


def test_the_tracker_scan_keeps_the_trained_horizon_unless_a_candidate_beats_it(tmp_path):
    run = _run(tmp_path)
    run.out.mkdir(exist_ok=True)  # prepare_run made it
    rounds = _rounds(run)
    chosen = choose_deployment(run, rounds.best, None)
    deploy = json.loads((run.out / "deploy.json").read_text())
    assert deploy["student"] == 0 and chosen in deploy["candidates"]
    trained, candidate = deploy["candidates"]
    better = (candidate["select_success_rate"], -candidate["select_miss_km_mean"]) > (
        trained["select_success_rate"], -trained["select_miss_km_mean"])
    assert chosen == (candidate if better else trained)
    # the record: the selected round's figures, with the tracker chosen for it
    write_run_record(run, rounds, rounds.best, None, None, chosen, RunClock())
    meta = json.loads((run.out / "metadata.json").read_text())
    assert meta["selected_round"] == 0 and meta["selected"] == {**rounds.records[0], "tracking": chosen}
    assert (run.out / "learning_curve.png").stat().st_size > 5_000


def test_the_relief_scan_flies_the_chosen_tracker_with_each_margin_and_keeps_the_best(tmp_path):
    run = _run(tmp_path, SMALL.replace("tracking_descent_mps", "load_relief_margins = [0.06, 0.02]\ntracking_descent_mps"))
    assert run.margins == [0.06, 0.02]
    run.out.mkdir(exist_ok=True)  # prepare_run made it
    rounds = _rounds(run)
    chosen = choose_deployment(run, rounds.best, None)
    deploy = json.loads((run.out / "deploy.json").read_text())
    trackers, relief = deploy["candidates"], deploy["relief_candidates"]
    assert [c["load_relief_margin"] for c in trackers] == [0.02, 0.02]  # the trackers fly the trained margin
    best_tracker = max(trackers, key=lambda c: (c["select_success_rate"], -c["select_miss_km_mean"]))
    # the chosen tracker, then each other margin (the trained 0.02 is flown once)
    assert relief[0] == best_tracker and [c["load_relief_margin"] for c in relief] == [0.02, 0.06]
    assert all(c["tracking_s"] == best_tracker["tracking_s"] for c in relief)
    assert chosen == max(relief, key=lambda c: (c["select_success_rate"], -c["select_miss_km_mean"]))
    student = json.loads((run.out / "student.json").read_text())
    assert student["load_relief_margin"] == chosen["load_relief_margin"]
    assert student.get("trained_load_relief_margin") == (None if chosen["load_relief_margin"] == 0.02 else 0.02)
    assert load_student(run.out).relief.margin == chosen["load_relief_margin"]
    for bad in ("[0.5, 1.0]", "0.04", "[true]"):
        with pytest.raises(ValueError, match=r"\[deploy\] load_relief_margins"):
            _run(tmp_path, SMALL.replace("tracking_descent_mps", f"load_relief_margins = {bad}\ntracking_descent_mps"))


def test_a_round_flies_its_own_load_relief_margin_and_a_resume_keeps_it(tmp_path):
    from rventry_agents.dagger import _take_round, round_law

    later = SMALL.replace("[fit]", "[[rounds]]\nepisodes = 1\nbeta = 0.0\nload_relief_margin = 0.05\n[fit]")
    run = _run(tmp_path, later)
    assert [round_law(run, k)["load_relief_margin"] for k in range(3)] == [0.02, 0.02, 0.05]
    assert round_law(run, 2)["horizon"] == run.law["horizon"]  # only the margin is the round's own
    # a resume takes a recorded round only when it flew the margin the config gives it
    run.out.mkdir(exist_ok=True)
    np.savez(run.out / "data_round_2.npz", x=np.zeros((3, N_FEATURES), np.float32), angles=np.zeros((3, 2), np.float32))
    flown = {"round": 2, "episodes": 1, "beta": 0.0, "samples": 3}
    for record in (flown, {**flown, "load_relief_margin": 0.04}):  # the [student] 0.02, or another
        with pytest.raises(ValueError, match=r"round 2 flew the load-relief margin 0.0[24], the config says 0.05"):
            _take_round(run, 2, 1, 0.0, record, Rounds())
    rounds = Rounds()
    _take_round(run, 2, 1, 0.0, {**flown, "load_relief_margin": 0.05}, rounds)
    assert rounds.laws == [round_law(run, 2)] and len(rounds.xs) == 1
    # the networks fitted after the rounds fly the last round's law; the relief scan starts from it
    rounds = _rounds(run)
    rounds.laws = [round_law(run, 0), round_law(run, 2)]
    best, final = refit_ensemble(run, rounds, RunClock(), resume=False)
    assert best.law == (rounds.laws[-1] if best.source == "final" else None)  # None: the synthetic round 0's
    chosen = choose_deployment(run, Selected("final", best.weights, best.members, best.hidden, rounds.laws[-1]), None)
    assert chosen["load_relief_margin"] == 0.05
    for bad in ("1.5", "true", '"4 %"'):
        with pytest.raises(ValueError, match=r"run.toml: \[rounds\]\[2\] load_relief_margin"):
            _run(tmp_path, later.replace("load_relief_margin = 0.05", f"load_relief_margin = {bad}"))


def _weights(out):
    """The saved network's tensors (by name) and its self-description (widths, members, inputs)."""
    import torch

    saved = torch.load(out / "student.pt", weights_only=True)
    tensors = saved["state_dict"] if "state_dict" in saved else saved
    about = {k: v for k, v in saved.items() if k != "state_dict"} if "state_dict" in saved else {}
    return {k: v.numpy() for k, v in tensors.items()}, about


def _without_wall(records):
    return [{k: v for k, v in r.items() if k != "wall_s"} for r in records]


@pytest.mark.slow
def test_two_runs_agree_and_a_resumed_run_equals_an_uninterrupted_one(tmp_path):
    three = SMALL.replace("[fit]", "[[rounds]]\nepisodes = 1\nbeta = 0.0\n[fit]")
    for name in ("a", "b"):
        (tmp_path / f"{name}.toml").write_text(three)
        train_dagger(tmp_path / f"{name}.toml", tmp_path / name, workers=1, progress_bar=False)
    (tmp_path / "c.toml").write_text(SMALL)  # interrupted after two rounds, then resumed with all three
    train_dagger(tmp_path / "c.toml", tmp_path / "c", workers=1, progress_bar=False)
    (tmp_path / "c.toml").write_text(three)
    (tmp_path / "c" / "student_round_1.pt").unlink()  # lost: the resume fits it again, bit for bit
    train_dagger(tmp_path / "c.toml", tmp_path / "c", workers=1, progress_bar=False, resume=True)
    runs = {name: tmp_path / name for name in "abc"}
    rounds = {n: _without_wall(json.loads((p / "rounds.json").read_text())) for n, p in runs.items()}
    assert rounds["a"] == rounds["b"] == rounds["c"]
    finals = {n: _without_wall([json.loads((p / "final.json").read_text())]) for n, p in runs.items()}
    assert finals["a"] == finals["b"] == finals["c"]
    w = {n: _weights(p) for n, p in runs.items()}
    assert w["a"][1] == w["b"][1] == w["c"][1] and w["a"][0].keys() == w["c"][0].keys() and len(w["a"][0]) >= 4
    for k in w["a"][0]:
        np.testing.assert_array_equal(w["a"][0][k], w["b"][0][k])
        np.testing.assert_array_equal(w["a"][0][k], w["c"][0][k])
    for name in ("student.json", "deploy.json"):
        assert len({(p / name).read_text() for p in runs.values()}) == 1


def test_the_learning_curve_labels_its_log_miss_axis_with_plain_numbers(tmp_path, monkeypatch):
    """Within one decade the miss axis has only minor ticks: they carry plain numbers, not 2x10^0."""
    import matplotlib.pyplot as plt

    from rventry_agents.dagger import plot_rounds

    figures = []
    monkeypatch.setattr("rventry_agents.dagger.save_figure", lambda fig, path, tight=True: figures.append(fig))
    rounds = [{"round": i, "select_success_rate": 0.1 * i, "flown_success_rate": 0.2, "select_miss_km_p50": m}
              for i, m in enumerate((2.6, 1.9, 1.3))]  # fmt: skip
    plot_rounds(rounds, tmp_path / "curve.png", {"distilled": {"select_success_rate": 0.5, "select_miss_km_p50": 1.2}})
    (fig,) = figures
    fig.canvas.draw()
    miss_axis = fig.axes[1].yaxis
    labels = [t.get_text() for t in miss_axis.get_majorticklabels() + miss_axis.get_minorticklabels() if t.get_text()]
    assert labels and all(float(x) > 0 for x in labels), labels  # parsed as plain numbers
    assert {"1.4", "2"} <= set(labels), labels
    plt.close(fig)
