"""Re-planning guidance (the agent ``mpc``): Example 2 solved again in flight, with estimated aerodynamics.

Every ``replan_s`` seconds the law solves the paper's Example 2 again, from the vehicle's
current state to the same terminal conditions (exact vertical impact on the target at
1219 m/s with alpha = 0), on the project's own LGR transcription of
:func:`~rventry_env.physics.entry_rhs`. The model in that problem carries the
drag-acceleration and lift-to-drag scale factors the accelerometer has measured
(:class:`~rventry_env.guidance.estimation.AeroScaleEstimator`) as NLP parameters, so one
transcription, built once per process, serves every solve. Between solves, TV-LQR
(:mod:`rventry_env.guidance.tvlqr`) tracks the current plan, with gains computed along it
for the estimated model, and a feedforward on any change of the estimate since the plan.

Design, each choice measured (``studies/mpc_settings.py``, numbers in the manual's guidance results):

* **Warm start.** A solve starts from the previous plan shifted in time (and its
  multipliers); the first one of an episode from a nominal plan solved once per process
  on the same mesh from the shipped optimum.
* **A mesh chosen for speed.** A fixed LGR mesh in normalized time: ``mesh_intervals``
  intervals of ``mesh_degree`` points plus a finer block over the last ``end_fraction``
  (the pull-up to vertical). As the horizon shrinks the same mesh grows finer in seconds.
* **Soft path constraints with small margins.** The plan keeps the load factor below
  ``1 - load_margin`` of 12 g and the dynamic pressure above ``1 + q_margin`` of 12 kPa,
  as soft constraints with an exact L1 penalty: a vehicle already outside them must
  still get a plan. The q margin covers what the accelerometer cannot tell: how much of
  a drag error is density (which sets q) rather than C_D.
* **A budget.** IPOPT stops after ``max_iterations`` iterations: the deterministic budget, so
  an episode's result does not depend on the machine's load. A wall-time cap ``max_wall_s``
  is an option for flight-like runs (off by default: a 2 s cap stopped 83 of 650 solves on a
  machine shared with three other jobs and changed the miss figures); a solve it stops is
  counted (``replan_timeouts``).
  A failed or unfinished solve keeps the previous plan, and is counted.
* **Freeze.** No new plan within ``freeze_s`` of the planned impact: the last plan is
  tracked into the ground.
* **alpha(t_f) = 0, flown** (``terminal_alpha``, on by default, aiming at 0.5 deg; off in
  :meth:`ReplanningSettings.flight_grade`, where the lift of the last seconds is what turns the
  velocity vertical when navigation errs in altitude, and the bound cost landings). The tracked alpha rate is capped by
  :func:`~rventry_env.guidance.terminal.alpha_rate_bound`, aiming at ``terminal_alpha_deg`` at
  impact, so that alpha reaches zero at impact even when the vehicle arrives off the plan's time.
  Tracking alone leaves 1.7 deg at the nominal impact. With a 1 s hold, the environment can take
  alpha to zero inside the step of impact only at that step's end, so the lift of the last step
  or two is the price: nominally, aiming at 1 / 0.5 / 0.2 deg leaves 0.91 / 0.45 / 0.18 deg and
  moves the vertical-impact error from 0.48 to 1.26 / 1.71 / 1.98 deg (J/J* 0.952 to 1.013 /
  1.056 / 1.084). Solving the last plan again with its duration a whole number of steps, so
  that the impact falls on a step's end, did not work: fixing the last minute's duration from
  58.23 s to 58 s took 137 IPOPT iterations and more than tripled the plan's cost.
* **Load relief between plans** (``load_relief_margin``, off by default until the defaults are
  chosen again on a flight-grade set). The tracked rates pass through
  :class:`~rventry_env.guidance.load_relief.LoadRelief`, which caps the alpha rate where the load
  factor predicted one control step ahead, calibrated on the accelerometer, would pass
  ``a_max (1 - margin)``: closed-loop feedback on the load, which the plans alone do not have
  between solves. Looking three steps ahead with the asked rate held, or with alpha held after
  one step, was too cautious: it capped the pull-up, and the optimum replayed through a density
  step ended 8-15 deg from vertical. With ``load_relief_sigmas`` the limit of each step is lowered
  by that many sigma of the density's and the aerodynamics' spread over the step (the same bands
  and Mach statistics as the plan's margins): a chance constraint on the next second, which costs
  nothing in a glide and a few per cent in a dive that drops a kilometre a second.
* **A q floor between plans** (``q_floor_margin``, off by default). Before the load relief the
  rates pass through :class:`~rventry_env.guidance.q_floor.QFloor`, which predicts a climbing
  vehicle's flight to its apex and rolls the lift away from the vertical where the apex's q,
  calibrated on the accelerometer, would fall under ``q_min (1 + margin)``.
* **Margins that follow the density's uncertainty** (``density_bands``, off by default). The
  accelerometer tells the density ratio where the vehicle is; elsewhere the plan extrapolates
  it. With the atmosphere's perturbation statistics known as Gauss-Markov bands in altitude
  (rms s(h), correlation length L(h): what an Earth-GRAM-style model publishes, not the
  episode's draw), the ratio at a node of altitude h differs from the one measured at h_now by
  s(h) sqrt(2 (1 - exp(-|h - h_now| / L(h)))) (1 sigma). Each node's load and q bounds are
  tightened by ``density_sigmas`` of it, through the NLP's constraint bounds (no new
  transcription): the plan keeps room where the air is least known, and none where it was
  just measured.
* **Margins that follow the aerodynamics' uncertainty in Mach** (``aero_mach_rms``, off by
  default). The estimator measures the drag and L/D scales at the Mach number flown; an
  aerodynamic database's error changes with Mach, and the final dive is flown 2-3 Mach numbers
  below the skip that measured it. With the error modelled as smooth in Mach (Legendre P1 and
  P2 terms over ``aero_mach_range``, each coefficient of rms ``aero_mach_rms``: the statistics of
  the database, not the episode's draw), the law (1) tightens each node's load bound by
  ``aero_sigmas`` of the coefficients' spread between the Mach flown and the node's, in
  quadrature with the density term, and (2) plans and tracks with the L/D scale lowered by
  ``aero_sigmas`` of its spread between the Mach flown and the impact's, so the plan keeps the
  lift the last minute may lack and turns the dive earlier.
* **The drag scale's split between density and C_D** (``drag_rms``, off by default). The
  accelerometer measures density x C_D; the plan's model puts it all on the density, so where C_D
  is 13 % high the plan's q is 13 % above the flown one, and a skip's apex that the plan holds at
  the q bound plus a fixed margin dips 10 % below it (a flight-grade draw, followed node by node).
  With the published rms of both (the density bands at the current altitude, ``drag_rms`` and the
  database's Mach error), the posterior share of ln k_D that is C_D tightens the q bound at every
  node, with ``split_sigmas`` of its spread: the margin grows where the measured drag is high and
  vanishes where it is low.
* **Final re-planning** (off by default). With ``final_replan_s`` set, the interval shortens
  to it once the planned time to go is under ``final_window_s``. The law itself does not need
  it (TV-LQR on a plan from at most a minute before lands every benchmark episode), but
  as a teacher it gives a student that has drifted off the plan a correction from where it
  is, rather than TV-LQR's pull back toward a path it can no longer reach.
* **A vertical dive** (``vertical_dive_m``, off by default). The plan ends vertical that high
  above the target, at the speed a straight dive needs to meet the final speed at the ground
  (:func:`~rventry_env.guidance.terminal.dive_entry_speed`); past the plan's end the law takes
  alpha to its final value and holds the bank. Meant for a navigated altitude that is off by
  up to that height at the end, which otherwise meets the ground mid-turn; on the ``flight``
  set it cost landings and nominal cost (the turn moves into thinner air).
* **Tracking with the estimate** (``track_estimate``, off by default). With the aerodynamic
  margin the plans assume a lower L/D than estimated; by default tracking compares the estimate
  with the plan in those same terms (no feedforward of the reserve). With this on, TV-LQR feeds
  the unlowered estimate forward and flies the planned path with the lift the vehicle has. On
  ``flight`` it cost landings.

The law sees only the navigation state and the sensed acceleration.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from functools import lru_cache

import numpy as np

from rventry_env.physics.entry import IDX
from rventry_env.task import EntryTask
from rventry_env.guidance.estimation import EstimatorSettings, FlightEstimatorSettings, make_estimator
from rventry_env.guidance.law import Law, Measurement
from rventry_env.guidance.terminal import alpha_rate_bound, dive_entry_speed
from rventry_env.guidance.tvlqr import StepLinearization, lqr_gains, sample_plan, tracking_weights
from rventry_env.physics.checks import check_flag, check_number, check_numbers, check_sequence
from rventry_env.physics.model import EntryModel
from rventry_env.physics.uncertainty import MachVaryingAerodynamics, mach_spread


@dataclass(frozen=True)
class ReplanningSettings:
    """Every default of the re-planning law (see the module docstring for each one's role)."""

    replan_s: float = 30.0
    mesh_intervals: int = 20
    mesh_degree: int = 4
    end_fraction: float = 0.05
    end_intervals: int = 4
    end_degree: int = 4
    q_margin: float = 0.05
    load_margin: float = 0.02
    soft_penalty: float = 30.0
    max_iterations: int = 80
    max_wall_s: float | None = None
    freeze_s: float = 30.0
    nlp_tolerance: float = 1e-6
    q_weight: float = 1e-5
    r_weight: float = 100.0
    final_replan_s: float | None = None
    final_window_s: float = 120.0
    terminal_alpha: bool = True
    terminal_alpha_deg: float = 0.5
    vertical_dive_m: float = 0.0
    track_estimate: bool = False
    load_relief_margin: float | None = None
    load_relief_sigmas: float = 0.0
    q_floor_margin: float | None = None
    drag_rms: float | None = None
    split_sigmas: float = 1.0
    density_bands: tuple | None = None
    density_sigmas: float = 2.0
    aero_mach_rms: float | None = None
    aero_sigmas: float = 1.0
    aero_mach_range: tuple = (MachVaryingAerodynamics.mach_low, MachVaryingAerodynamics.mach_high)

    def __post_init__(self):
        if self.density_bands is not None:
            from rventry_env.task.flight_grade import parse_bands

            object.__setattr__(self, "density_bands", parse_bands(self.density_bands, "density_bands"))
        check_numbers(self, ("replan_s", "soft_penalty", "nlp_tolerance", "r_weight"), low=0.0, low_open=True)
        check_numbers(self, ("mesh_intervals", "mesh_degree", "end_intervals", "end_degree", "max_iterations"), low=1,
                      integer=True)  # fmt: skip
        check_numbers(self, ("end_fraction", "q_margin", "load_margin"), low=0.0, high=0.5, high_open=True)
        check_numbers(self, ("freeze_s", "q_weight", "final_window_s", "terminal_alpha_deg", "density_sigmas",
                             "aero_sigmas", "split_sigmas", "load_relief_sigmas"), low=0.0)  # fmt: skip
        check_number(self, "vertical_dive_m", low=0.0, high=20_000.0)  # m; 0: vertical at the ground
        check_number(self, "max_wall_s", low=0.0, low_open=True, optional=True)  # None: no cap
        check_number(self, "final_replan_s", low=0.0, low_open=True, high=self.replan_s, optional=True)
        check_number(self, "load_relief_margin", low=0.0, high=1.0, high_open=True, optional=True)
        check_numbers(self, ("q_floor_margin", "drag_rms", "aero_mach_rms"), low=0.0, optional=True)
        check_flag(self, "terminal_alpha")
        check_flag(self, "track_estimate")
        check_sequence(self, "aero_mach_range")
        r = tuple(self.aero_mach_range)
        if not (len(r) == 2 and 0 < r[0] < r[1]):
            raise ValueError(f"ReplanningSettings.aero_mach_range must be (low, high) Mach numbers with 0 < low < high, "
                             f"got {self.aero_mach_range!r}")  # fmt: skip
        if self.drag_rms is not None and self.density_bands is None:
            raise ValueError("ReplanningSettings.drag_rms needs density_bands to split the drag scale against")
        if self.load_relief_sigmas > 0 and (self.load_relief_margin is None or
                                            (self.density_bands is None and self.aero_mach_rms is None)):  # fmt: skip
            raise ValueError("ReplanningSettings.load_relief_sigmas needs load relief (load_relief_margin) and the "
                             "uncertainty it counts (density_bands and/or aero_mach_rms)")

    @classmethod
    def flight_grade(cls, **changes) -> "ReplanningSettings":
        """The settings for flight-grade uncertainty (agent ``mpc-flight``, which pairs them with
        :meth:`~rventry_env.guidance.estimation.FlightEstimatorSettings.flight_grade`): load relief
        between plans (4 %), a q margin of 10 %, no terminal alpha bound (on 30 ``flight`` episodes
        it landed 0.77 against 0.90 without), and margins from the atmosphere's and the
        aerodynamic database's published uncertainty (the ``flight`` set's Gauss-Markov density bands
        and its 3 % rms per Legendre coefficient of C_L and C_D in Mach), each at 1 sigma. Chosen on
        20-30 episodes of the ``flight`` set away from the evaluation's seeds (docs/guidance.md);
        ``changes`` override any field."""
        from rventry_env.task import FLIGHT_GRADE_ERRORS as F

        base = dict(terminal_alpha=False, load_relief_margin=0.04, q_margin=0.10, density_bands=F.density_bands,
                    density_sigmas=1.0, aero_mach_rms=max(F.lift_mach, F.drag_mach), aero_sigmas=1.0)  # fmt: skip
        return cls(**(base | changes))

    def replan_interval(self, time_to_go: float) -> float:
        """Seconds to the next plan, given the current plan's time to go."""
        if self.final_replan_s is not None and time_to_go <= self.final_window_s:
            return float(self.final_replan_s)
        return float(self.replan_s)


def replanning_mesh(s: ReplanningSettings):
    """The re-planning mesh in normalized time: uniform intervals, then an end block over the last
    ``end_fraction`` whose intervals shrink geometrically toward the impact (each half the one before).

    The optimum ends by driving alpha to zero at its rate bound in the last half second, as the
    load factor climbs in the thickening air. Equal end intervals could not follow it: the plan's
    polynomials overshot between nodes and its load factor reached 12.7 g in the last second,
    which the flown vehicle then did too.
    """
    from rventry_env.reference.collocation import Mesh
    from rventry_env.reference.pipeline import end_clustered_mesh

    if s.end_fraction == 0:
        return Mesh.uniform(s.mesh_intervals, s.mesh_degree)
    return end_clustered_mesh(s.mesh_intervals, s.mesh_degree, s.end_fraction, s.end_intervals, s.end_degree, 0.5)


class _Shifted:
    """A solved plan seen from ``shift`` seconds later (time 0 = then): a warm-start guess."""

    t0 = 0.0

    def __init__(self, sol, shift: float):
        self.sol, self.shift = sol, float(shift)

    @property
    def tf(self) -> float:
        return self.sol.tf - self.shift

    def state(self, t):
        return self.sol.state(np.asarray(t, dtype=float) + self.shift)

    def control(self, t):
        return self.sol.control(np.asarray(t, dtype=float) + self.shift)


class PlanSolver:
    """The re-planning NLP: compiled and transcribed once, solved from any state and estimate.

    :param task: the problem's constants (bounds, terminal conditions).
    :param model: the nominal model; the estimates scale it.
    :param settings: :class:`ReplanningSettings`.
    """

    def __init__(self, task: EntryTask, model: EntryModel, settings: ReplanningSettings):
        from rventry_env.reference.collocation import CompiledProblem, SolverOptions, transcribe
        from rventry_env.reference.entry_ocp import EntryOcpConfig, entry_ocp

        s = self.settings = settings
        p = task.problem
        self.model = model
        self.radius = model.planet.radius
        problem = replace(p, q_min=p.q_min * (1 + s.q_margin), a_max_g=p.a_max_g * (1 - s.load_margin))
        if s.vertical_dive_m > 0:  # the plan ends vertical above the target; the law dives from there
            problem = replace(problem, final_altitude=p.final_altitude + s.vertical_dive_m,
                              final_speed=dive_entry_speed(task, model, s.vertical_dive_m))  # fmt: skip
        config = EntryOcpConfig(problem=problem, model=model, tf_bounds=(1.0, 3000.0),
                                    soft_path_penalty=s.soft_penalty, aero_scale_parameters=True)  # fmt: skip
        self.config, self.problem = config, entry_ocp(config)
        self.compiled = CompiledProblem(self.problem)
        mesh = replanning_mesh(s)
        ipopt = {"mu_init": 1e-4, "warm_start_init_point": "yes",
                 "warm_start_bound_push": 1e-6, "warm_start_mult_bound_push": 1e-6,
                 "warm_start_slack_bound_push": 1e-6}  # fmt: skip
        if s.max_wall_s is not None:
            ipopt["max_wall_time"] = float(s.max_wall_s)
        self.ipopt_options = dict(ipopt)
        opts = SolverOptions(graph="sx", nlp_tolerance=s.nlp_tolerance, max_nlp_iterations=s.max_iterations,
                             warm_ipopt={}, ipopt=ipopt)  # fmt: skip
        start = time.perf_counter()
        self.transcription = transcribe(self.compiled, mesh, opts)
        self.build_time_s = time.perf_counter() - start

    def solve(self, x0: np.ndarray, theta: np.ndarray, guess, warm=None):
        """A plan from state ``x0`` (time 0) for log-scales ``theta``.

        :param guess: anything with ``t0``, ``tf``, ``state``, ``control`` (the previous plan, shifted).
        :param warm: a previous solution whose multipliers start this solve.
        :return: the :class:`~rventry_env.reference.collocation.CollocationSolution` (check ``success``).
        """
        from rventry_env.reference.collocation import initial_point, solve_from

        tr = self.transcription
        lbx, ubx = tr.bounds_with_initial_state(x0)
        z0 = initial_point(tr, guess, lbx, ubx)
        lam = (warm.lam_x, warm.lam_g) if warm is not None and warm.lam_x is not None else (None, None)
        lbg, ubg = self.path_bounds(x0, guess, theta)
        return solve_from(tr, z0, theta, lbx, ubx, *lam, lbg=lbg, ubg=ubg)

    def density_sigma(self, altitude_now: float, altitudes: np.ndarray) -> np.ndarray:
        """1-sigma relative uncertainty of the density ratio at ``altitudes`` given its value at
        ``altitude_now`` (:class:`ReplanningSettings` ``density_bands``; zeros without them)."""
        s = self.settings
        if s.density_bands is None:
            return np.zeros_like(altitudes)
        from rventry_env.task.flight_grade import band_spread

        return band_spread(s.density_bands, altitude_now, altitudes)

    def aero_sigma(self, mach_now, machs) -> np.ndarray:
        """1-sigma relative uncertainty of C_L (or C_D) at ``machs`` given its value at ``mach_now``
        (:class:`ReplanningSettings` ``aero_mach_rms``; zeros without it).

        The aerodynamic database's error is modelled as smooth in Mach: a relative error
        a1 P1(s) + a2 P2(s) over ``aero_mach_range`` (s in [-1, 1], held outside), each coefficient
        of rms ``aero_mach_rms``. The estimator measures the error where the vehicle flies; at
        another Mach it differs by a1 dP1 + a2 dP2, whose spread is rms |(dP1, dP2)|.
        """
        s = self.settings
        machs = np.asarray(machs, dtype=float)
        if s.aero_mach_rms is None:
            return np.zeros_like(machs)
        return mach_spread(s.aero_mach_rms, np.asarray(mach_now, dtype=float), machs, *s.aero_mach_range)

    def mach(self, x: np.ndarray) -> np.ndarray:
        """The nominal model's Mach number at states ``x`` (..., 12)."""
        from rventry_env.physics.entry import entry_forces

        x = np.atleast_2d(np.asarray(x, dtype=float))
        return np.asarray(entry_forces(tuple(x.T), self.model).mach, dtype=float)

    def drag_split(self, x0: np.ndarray, ln_kd: float) -> tuple[float, float]:
        """How much of the measured drag scale is not density: (mean, sigma) of ln(k_D / density ratio)
        at ``x0`` (:class:`ReplanningSettings` ``drag_rms``; (0, 0) without it).

        The accelerometer measures k_D = density ratio x C_D ratio and cannot split it; the plan's
        model puts it all on the density, so its q is the true one times the C_D ratio. With the
        density's published rms at this altitude (``density_bands``) and the drag coefficient's
        (``drag_rms``, with the database's Mach error at this Mach), the split's posterior puts the
        fraction s_c^2 / (s_rho^2 + s_c^2) of ln k_D on C_D, give or take s_rho s_c / sqrt(s_rho^2 + s_c^2).
        """
        s = self.settings
        if s.drag_rms is None:
            return 0.0, 0.0
        from rventry_env.task.flight_grade import band_profile

        s_rho = float(band_profile(s.density_bands, np.array([float(x0[IDX.r]) - self.radius]))[0][0])
        s_c = s.drag_rms
        if s.aero_mach_rms is not None:  # the database's error at this Mach, relative to its mean over the range
            s_c = math.hypot(s_c, float(mach_spread(s.aero_mach_rms, 0.5 * sum(s.aero_mach_range),
                                                    self.mach(x0)[0], *s.aero_mach_range)))  # fmt: skip
        total = s_rho**2 + s_c**2
        if total == 0:
            return 0.0, 0.0
        return float(ln_kd) * s_c**2 / total, s_rho * s_c / math.sqrt(total)

    def path_bounds(self, x0: np.ndarray, guess, theta=None):
        """The NLP's constraint bounds for a solve from ``x0`` with log-scales ``theta``: the
        transcription's, with each collocation point's load and q bounds tightened by
        ``density_sigmas`` of the density ratio's uncertainty at the altitude ``guess`` puts it, the
        load bound also by ``aero_sigmas`` of the aerodynamic coefficients' uncertainty at the Mach
        number it puts it (the two in quadrature), and the q bound by the drag scale's share that is
        not density (:meth:`drag_split`: its mean, and ``split_sigmas`` of its spread in quadrature
        with the density term). None, None: unchanged."""
        s, tr = self.settings, self.transcription
        density = s.density_bands is not None and s.density_sigmas > 0
        aero = s.aero_mach_rms is not None and s.aero_sigmas > 0
        split = s.drag_rms is not None
        if not (density or aero or split):
            return None, None
        nodes = tr.mesh.nodes()[: tr.mesh.n_collocation]
        x = np.asarray(guess.state(guess.t0 + nodes * (guess.tf - guess.t0)), dtype=float)
        k_q = s.density_sigmas * self.density_sigma(float(x0[IDX.r]) - self.radius, x[:, IDX.r] - self.radius)
        k_a = s.aero_sigmas * self.aero_sigma(self.mach(x0)[0], self.mach(x)) if aero else 0.0
        k_n = np.hypot(k_q, k_a)
        mean, spread = self.drag_split(x0, 0.0 if theta is None else float(theta[0]))
        q_shift = mean + np.hypot(k_q, s.split_sigmas * spread)
        lbg, ubg = tr.lbg.copy(), tr.ubg.copy()
        # the path rows are point-major: every path constraint (relative) at each collocation point
        names = [c.name for c in self.problem.path_constraints]
        load, q = names.index("aero_accel"), names.index("dynamic_pressure")
        ubg[tr.g_groups["path"]][load :: len(names)] *= np.exp(-k_n)  # n / n_max' <= exp(-k sigma)
        lbg[tr.g_groups["path"]][q :: len(names)] *= np.exp(q_shift)  # q / q_min' >= exp(shift)
        return lbg, ubg

    def nominal_plan(self, task: EntryTask):
        """The plan for the nominal start and model on this mesh, from the shipped optimum (cached)."""
        if getattr(self, "_nominal", None) is None:
            from rventry_env.reference import load_reference
            from rventry_env.reference.guess import ReferenceGuess

            x0 = task.problem.initial_state(self.radius)
            sol = self.solve(x0, np.zeros(2), ReferenceGuess(load_reference(), self.config))
            # before flight, not in it: the budget per solve is the in-flight one, so continue
            # from where a solve stopped until it converges
            for _ in range(20):
                if sol.success:
                    break
                sol = self.solve(x0, np.zeros(2), _Shifted(sol, 0.0), sol)
            if not sol.success:
                raise RuntimeError(f"the nominal plan did not converge on the re-planning mesh ({sol.status})")
            self._nominal = sol
        return self._nominal


@lru_cache(maxsize=4)
def _plan_solver(task: EntryTask, model: EntryModel, settings: ReplanningSettings) -> PlanSolver:
    return PlanSolver(task, model, settings)


@dataclass
class _Track:
    """One episode's current plan and the TV-LQR gains along it."""

    t_start: float  # the plan's time 0, in episode time
    solution: object
    theta: np.ndarray  # the log-scales it was solved with
    x_ref: np.ndarray
    u_ref: np.ndarray
    gains: np.ndarray
    theta_gains: np.ndarray

    @property
    def t_end(self) -> float:
        return self.t_start + self.solution.tf

    def step(self, time_s: float, dt: float) -> int:
        """The index of the control step at episode time ``time_s`` along this plan's samples."""
        return int(round((time_s - self.t_start) / dt))


@dataclass
class _EpisodeLog:
    replans: int = 0
    replan_failures: int = 0
    replan_timeouts: int = 0
    solve_times: list = field(default_factory=list)
    iterations: list = field(default_factory=list)
    failures: list = field(default_factory=list)  # (time, status)


class ReplanningGuidance(Law):
    """The re-planning law (agent ``mpc``): batched over episodes, one plan each.

    :param task: the task (problem constants, dt).
    :param model: the nominal model.
    :param settings: :class:`ReplanningSettings`.
    :param estimator_settings: the filter's settings: :class:`~rventry_env.guidance.estimation.EstimatorSettings`
        for the scalar filters on the two scales, :class:`~rventry_env.guidance.estimation.FlightEstimatorSettings`
        for the flight-grade filter (scales as processes in altitude and Mach, and the wind).
    """

    episodes_per_task = 1  # seconds per episode: parallel evaluations give each episode its own task
    retargets = True  # an episode told another target plans to it (its own transcription, built once per target)

    def __init__(self, task: EntryTask | None = None, model: EntryModel | None = None,
                 settings: ReplanningSettings | None = None,
                 estimator_settings: EstimatorSettings | FlightEstimatorSettings | None = None):  # fmt: skip
        self.task = EntryTask() if task is None else task
        self.model = EntryModel() if model is None else model
        self.settings = ReplanningSettings() if settings is None else settings
        self.solver = _plan_solver(self.task, self.model, self.settings)
        self.linearization = StepLinearization(self.task, self.model)
        self.weights = tracking_weights(self.task, self.settings.q_weight, self.settings.r_weight)
        p = self.task.problem
        self.u_max = np.array([p.u_alpha_max, p.u_sigma_max])
        self.estimator = make_estimator(self.model, 1, estimator_settings)
        self.nominal = self.solver.nominal_plan(self.task)
        self.mach_end = float(self.solver.mach(self.nominal.state(self.nominal.tf))[0])  # the nominal impact's
        self.relief = None
        if self.settings.load_relief_margin is not None:
            from rventry_env.guidance.load_relief import LoadRelief

            s = self.settings
            self.relief = LoadRelief(self.model, self.task, s.load_relief_margin, sigmas=s.load_relief_sigmas,
                                     density_bands=s.density_bands, aero_mach_rms=s.aero_mach_rms,
                                     aero_mach_range=s.aero_mach_range)  # fmt: skip
        self.q_floor = None
        if self.settings.q_floor_margin is not None:
            from rventry_env.guidance.q_floor import QFloor

            self.q_floor = QFloor(self.model, self.task, self.settings.q_floor_margin)
        self.reset(1)

    def reset(self, n_episodes: int) -> None:
        """New episodes: no plan, the estimates at their prior, empty logs."""
        self.n = int(n_episodes)
        self.estimator.reset(self.n)
        self.tracks: list[_Track | None] = [None] * self.n
        # each episode's planner and its nominal plan: the task's, until told another target
        self.solvers = [self.solver] * self.n
        self.nominals = [self.nominal] * self.n
        self.aimed = [None] * self.n  # the target each episode's planner aims at (None: the task's)
        self.last_replan = np.full(self.n, -np.inf)
        self.logs = [_EpisodeLog() for _ in range(self.n)]
        for limiter in (self.q_floor, self.relief):
            if limiter is not None:
                limiter.reset(self.n)

    # ------------------------------------------------------------------ planning
    def _track(self, t_start: float, sol, theta: np.ndarray) -> _Track:
        dt = self.task.dt
        x_ref, u_ref = sample_plan(sol, dt)
        a, b, g = self.linearization.along(x_ref[:-1], u_ref, theta)
        gains, theta_gains = lqr_gains(a, b, *self.weights, g=g)
        return _Track(t_start, sol, np.asarray(theta, float).copy(), x_ref, u_ref, gains, theta_gains)

    def _replan(self, i: int, t: float, x: np.ndarray, theta: np.ndarray) -> None:
        log = self.logs[i]
        old = self.tracks[i]
        if old is None:
            guess, warm = self.nominals[i], self.nominals[i]
        else:
            guess, warm = _Shifted(old.solution, t - old.t_start), old.solution
        start = time.perf_counter()
        sol = self.solvers[i].solve(x, theta, guess, warm)
        elapsed = time.perf_counter() - start
        log.replans += 1
        log.solve_times.append(elapsed)
        log.iterations.append(sol.nlp_iterations)
        if sol.success and math.isfinite(sol.tf) and sol.tf > 0:
            self.tracks[i] = self._track(t, sol, theta)
        else:
            log.replan_failures += 1
            log.replan_timeouts += sol.status == "Maximum_WallTime_Exceeded"
            log.failures.append((round(t, 3), sol.status))
            if old is None:  # nothing to keep: fly the nominal plan, the estimate fed forward
                self.tracks[i] = self._track(t, self.nominals[i], np.zeros(2))
        self.last_replan[i] = t

    def _aim(self, target_e: np.ndarray) -> None:
        """Point each episode's planner at the target it is told (a change re-plans at once)."""
        nominal = self.task.problem.target_unit_vector()
        for i in range(self.n):
            t = np.asarray(target_e[i], dtype=float)
            if self.aimed[i] is not None and np.array_equal(t, self.aimed[i]):
                continue
            # the task's own target keeps the task's planner (aimed_at rounds it through lat/lon)
            task = self.task if np.allclose(t, nominal, rtol=0.0, atol=1e-12) else self.task.aimed_at(t)
            solver = _plan_solver(task, self.model, self.settings)
            if solver is not self.solvers[i]:
                self.solvers[i] = solver
                self.nominals[i] = solver.nominal_plan(task)
                self.tracks[i] = None  # a plan to the old target is no plan
            self.aimed[i] = t.copy()

    # ------------------------------------------------------------------ the law
    def rates(self, time_s, state, theta) -> np.ndarray:
        """Commanded (u_alpha, u_sigma) in rad/s for every episode, from its current plan."""
        u = np.zeros((self.n, 2))
        dt = self.task.dt
        dive = self.settings.vertical_dive_m > 0
        for i, tr in enumerate(self.tracks):
            if tr is None:
                continue
            if time_s[i] >= tr.t_end:
                if dive:  # past the plan's end: straight down, alpha to the plan's final, the bank still
                    u[i, 0] = (self.task.problem.final_alpha - state[i, IDX.alpha]) / dt
                continue
            k = min(tr.step(time_s[i], dt), tr.u_ref.shape[0] - 1)
            u[i] = (tr.u_ref[k] - tr.gains[k] @ (state[i] - tr.x_ref[k])
                    - tr.theta_gains[k] @ (theta[i] - tr.theta))  # fmt: skip
        return u

    def planned_angles(self, time_s, state, ahead_s=None) -> np.ndarray:
        """(alpha, sigma) in rad that each episode's current plan holds ``ahead_s`` (a number or one
        per episode; default one control step) ahead, its final angles past its end, the current
        angles without a plan.

        A teacher's label for a student that commands angles: where the law is taking the angles.
        A plan starts from the current angles, and the rate bounds and the rates' cost keep it near
        them for a second or two, so a few seconds ahead is what the law wants, not where it is.
        """
        time_s = np.asarray(time_s, dtype=float)
        out = np.array(state, dtype=float)[:, IDX.angles]
        ahead = np.broadcast_to(self.task.dt if ahead_s is None else np.asarray(ahead_s, dtype=float), time_s.shape)
        steps = np.maximum(np.rint(ahead / self.task.dt).astype(int), 1)
        for i, tr in enumerate(self.tracks):
            if tr is None:
                continue
            k = tr.step(time_s[i], self.task.dt) + int(steps[i])
            out[i] = tr.x_ref[min(max(k, 0), tr.x_ref.shape[0] - 1), IDX.angles]
        return out

    def planning_scales(self, state, theta) -> np.ndarray:
        """The log-scales (N, 2) the plans and their tracking use: the estimate, with the
        lift-to-drag scale lowered by ``aero_sigmas`` of its uncertainty between the Mach number
        flown now and the impact's (:meth:`PlanSolver.aero_sigma`; lift and drag errors independent,
        so sqrt(2) of one coefficient's). The plan keeps the lift the rest of the flight may lack
        (a pessimistic L/D turns the final dive earlier), and tracking compares like with like."""
        s = self.settings
        if s.aero_mach_rms is None or s.aero_sigmas == 0:
            return theta
        out = np.array(theta, dtype=float)
        out[:, 1] -= s.aero_sigmas * math.sqrt(2.0) * self.solver.aero_sigma(self.solver.mach(state), self.mach_end)
        return out

    def __call__(self, m: Measurement) -> np.ndarray:
        time_s, state = m.time_s, m.navigation_state
        if m.n != self.n:
            self.reset(m.n)
        estimate = self.estimator.observe(m)
        theta = self.planning_scales(state, estimate)
        if m.target_e is not None:
            self._aim(m.target_e)
        for i in range(self.n):
            tr = self.tracks[i]
            to_go = tr.t_end - time_s[i] if tr is not None else np.inf
            due = tr is None or (time_s[i] - self.last_replan[i] >= self.settings.replan_interval(to_go)
                                 and to_go > self.settings.freeze_s)  # fmt: skip
            if due:
                self._replan(i, float(time_s[i]), state[i], theta[i])
        u = self.rates(time_s, state, estimate if self.settings.track_estimate else theta)
        if self.settings.terminal_alpha:
            u[:, 0] = np.minimum(u[:, 0], alpha_rate_bound(state, self.task, self.model.planet.radius,
                                                           tolerance=math.radians(self.settings.terminal_alpha_deg)))
        rates = np.clip(u / self.u_max, -1.0, 1.0)
        for limiter in (self.q_floor, self.relief):
            if limiter is not None:
                rates = limiter(rates, state, m.sensed_accel_b, count=m.flying)
        return rates.astype(np.float32)

    def episode_stats(self) -> list[dict]:
        """Per episode: ``replans``, ``replan_failures``, solve-time percentiles (s) and IPOPT iterations."""
        out = []
        for log in self.logs:
            t = np.asarray(log.solve_times)
            out.append({
                "replans": log.replans,
                "replan_failures": log.replan_failures,
                "replan_timeouts": log.replan_timeouts,
                "solve_time_s": ({f"p{q}": float(np.percentile(t, q)) for q in (50, 90, 99)} | {"max": float(t.max())})
                if t.size else None,
                "first_solve_s": float(t[0]) if t.size else None,
                "solve_iterations_median": float(np.median(log.iterations)) if log.iterations else None,
                "replan_failure_events": [list(f) for f in log.failures],
                "solve_times_s": [round(float(x), 5) for x in t],
            })  # fmt: skip
        for name, limiter in (("load_relief_steps", self.relief), ("q_floor_steps", self.q_floor)):
            if limiter is not None:
                for rec, k in zip(out, limiter.steps):
                    rec[name] = int(k)
        return out


__all__ = ["ReplanningSettings", "PlanSolver", "ReplanningGuidance"]
