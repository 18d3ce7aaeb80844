"""A population of simulated participants: parameter distributions and per-participant draws.

A population file (``protocols/population.toml``) names its simulated-user model in its
``[population]`` table (``model = "..."``, default ``"interface"``: :mod:`study.simulated.models`)
and gives one table per parameter group of that model; each key is one parameter and holds a
distribution (see :mod:`study.simulated.distributions`). The default model's groups are seven
tables, ``[motor]``, ``[reaction]``, ``[surprise]``, ``[trust]``, ``[grasp]``, ``[questionnaire]``
and ``[interface]``, the fields of :class:`ParticipantParams`. Participant ``i`` of a run
with seed ``s`` is drawn from ``Generator(PCG64(SeedSequence([s, i])))``: the same participant
gets the same parameters whatever the number of participants or workers.
"""

from __future__ import annotations

import dataclasses
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from app.files import InputFileError, read_bytes_file
from study.protocol.loader import MAX_NESTING, nesting_depth
from study.simulated.distributions import Distribution
from study.simulated.errors import PopulationError
from study.simulated.models import DEFAULT_MODEL, UserModel, get_model

DEFAULT_POPULATION_PATH = Path(__file__).resolve().parents[2] / "protocols" / "population.toml"
MAX_POPULATION_BYTES = 2**20
"""Largest population file read (the shipped one is about 5 KB)."""


@dataclass(frozen=True)
class MotorParams:
    """Goal-directed movement of the gizmo target (see :mod:`study.simulated.user_model`)."""

    reaction_delay_s: float  # tau: the user acts on what they saw tau seconds ago
    fitts_a_s: float  # movement time T = a + b log2(1 + D / W)
    fitts_b_s_per_bit: float
    fitts_width_m: float  # W
    noise_sd_m: float  # stationary sd of the Ornstein-Uhlenbeck hand noise
    noise_tau_s: float  # its correlation time
    follow_lag_s: float  # how the user expects the gripper to trail their target (training)
    feedback_gain_per_s: float  # k: dc/dt = k (m - ee) outside the dead zone
    feedback_deadzone_m: float
    correction_leak_s: float  # corrections fade back to the plan: dc/dt -= c / leak
    wait_lag_m: float  # robot this far behind the expected position: the plan waits for it
    max_gain_per_s: float  # cap on k (1 + f) (1 - rho), keeps the delayed loop stable


@dataclass(frozen=True)
class ReactionParams:
    """Reaction to the robot: steering against it (Figs. 14-15), relaxing when helped (Fig. 12)."""

    opposition_angle_deg: float  # robot motion more than this off the goal direction = opposing
    opposition_speed_m_s: float  # slower robot motion is not noticed
    opposition_deviation_m: float  # the robot this far from where expected = full opposition
    fight_rate_per_s: float  # df/dt = rate * o while opposed
    fight_decay_s: float  # df/dt = -f / decay once it stops
    fight_max: float
    fight_push_m: float  # hand displacement against the robot per unit of f
    relaxer: float  # 1 if this participant lets the robot finish when it helps, else 0
    relax_depth: float  # how far a relaxer lets go, rho -> depth
    relax_time_s: float  # time constant of rho
    relax_lead_m: float  # robot this far ahead of the hand = full help
    careless_noise_gain: float  # noise sd multiplied by (1 + gain * rho)


@dataclass(frozen=True)
class SurpriseParams:
    """Stopping to re-plan after an unexpected robot motion (:mod:`study.simulated.surprise`)."""

    threshold_m: float  # theta: the gripper this far astray of the forward model = surprise
    horizon_s: float  # H: the prediction error is accumulated over about this long
    adapt_s: float  # the robot's own motion, once seen, is expected after about this long
    expected_speed_m_s: float  # the gripper was seen to follow the handle at most this fast
    replan_s: float  # median stop to re-plan after a surprise (per surprise x exp(sigma z))
    replan_sigma: float


@dataclass(frozen=True)
class TrustParams:
    """Trust in the robot across a participant's runs (:mod:`study.simulated.trust`)."""

    initial: float  # T0: trust before the first run, and what it recovers toward
    recovery_per_run: float  # rho: share of the shortfall T0 - T made up from one run to the next
    opposition_loss_per_s: (
        float  # lambda: dT/dt = -lambda o T while the robot opposes (o in [0, 1])
    )
    wrong_approach_loss: float  # T <- T (1 - delta) when the robot takes the gripper to the other
    wrong_approach_m: float  # object: within this of its grasp point, the user's handle farther
    knock_loss: float  # T <- T (1 - delta) for each object seen knocked over or off the table
    distrust_fight_gain: float  # the fight builds (1 + g (1 - T)) times as fast


@dataclass(frozen=True)
class GraspParams:
    """When the gripper is closed, lifted, and how it goes wrong."""

    grasp_radius_m: float  # close when the seen gripper is this near the grasp point ...
    settle_speed_m_s: float  # ... and moving slower than this
    early_grasp_p: float  # per attempt: close already at early_radius_m
    early_radius_m: float
    miss_p: float  # per attempt: aim at a point miss_offset_m beside the object
    miss_offset_m: float
    close_wait_s: float  # at least this long with the gripper closed before lifting
    lift_m: float  # how high the target is raised after closing
    check_after_s: float  # this long after closing, an empty gripper is noticed
    retry_pause_s: float  # pause with the gripper open before reaching again
    stall_radius_m: float  # the gripper stopped getting nearer while within this ...
    stall_time_s: float  # ... for this long: close anyway ("as near as it gets")
    notice_read_s: float  # the gripper held above the object: the page's notice read, re-aim


@dataclass(frozen=True)
class InterfaceParams:
    """Which of the page's inputs the participant uses and how (:mod:`study.simulated.interface`)."""

    keyboard: float  # 1: steers with the held keys, 0: drags the gizmo's handles
    drag_a_s: float  # one drag of a handle lasts T = a + b log2(1 + D / W) (mouse dragging)
    drag_b_s_per_bit: float
    regrab_s: float  # median pause between letting go of a handle and grabbing the next one
    regrab_sigma: float  # lognormal spread of those pauses
    depth_error_sd: float  # the part of a drag along the viewing direction is off by this share
    plane_share: float  # drag the table-plane handle when the smaller horizontal component
    # of the error is at least this share of it; otherwise the single axis
    tolerance_m: float  # handle errors below this are left alone
    key_anticipation: float  # share of their delay a key user anticipates when letting go
    view_azimuth_deg: float  # the page's camera: direction from the task to the camera
    view_elevation_deg: float


@dataclass(frozen=True)
class QuestionnaireParams:
    """Answers (see :mod:`study.simulated.questionnaire`)."""

    control_bias: float  # kappa: disagreement weighs (1 + kappa) times as much
    rating_offset: float  # personal generosity on every item (scale points)
    time_weight: float  # scale points per unit of log(duration / training duration)
    disagreement_weight: float  # scale points per unit of mean disagreement in [0, 1]
    failure_penalty: float  # scale points for a run that did not end in success
    preference_gain: float  # exaggeration of the preference answer
    noise_sd: float  # sd of the answer noise (scale points)


@dataclass(frozen=True)
class ParticipantParams:
    """Everything that makes one simulated participant who they are."""

    index: int
    seed: int
    motor: MotorParams
    reaction: ReactionParams
    surprise: SurpriseParams
    trust: TrustParams
    grasp: GraspParams
    questionnaire: QuestionnaireParams
    interface: InterfaceParams


INTERFACE_SECTIONS: dict[str, type] = {
    "motor": MotorParams,
    "reaction": ReactionParams,
    "surprise": SurpriseParams,
    "trust": TrustParams,
    "grasp": GraspParams,
    "questionnaire": QuestionnaireParams,
    "interface": InterfaceParams,
}
"""The parameter groups of the default model (``interface``): one population table each."""


@dataclass(frozen=True)
class Population:
    """Distributions of every parameter of the simulated-user ``model``, by section and name."""

    distributions: Mapping[str, Mapping[str, Distribution]]
    source: str = "<dict>"
    model_name: str = DEFAULT_MODEL

    @property
    def model(self) -> UserModel:
        """The simulated-user model this population's people follow."""
        return get_model(self.model_name)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, source: str = "<dict>") -> Population:
        """Validate a parsed population table; every error names ``source`` and the key path."""
        model = _model(data, source)
        unknown = sorted(set(data) - set(model.sections) - {"population"})
        if unknown:
            raise PopulationError(
                f"{source}: unknown table(s) {unknown}; the {model.name!r} model expects"
                f" {sorted(model.sections)}"
            )
        out: dict[str, dict[str, Distribution]] = {}
        for section, kind in model.sections.items():
            table = data.get(section)
            if not isinstance(table, Mapping):
                raise PopulationError(f"{source}: missing table [{section}]")
            names = [f.name for f in dataclasses.fields(kind)]
            extra = sorted(set(table) - set(names))
            if extra:
                raise PopulationError(
                    f"{source}: {section}.{extra[0]} is not a parameter; known: {', '.join(names)}"
                )
            missing = [n for n in names if n not in table]
            if missing:
                raise PopulationError(
                    f"{source}: {section} is missing {', '.join(missing)}"
                    " (every parameter needs a distribution)"
                )
            out[section] = {
                n: Distribution.from_config(table[n], where=f"{source}: {section}.{n}")
                for n in names
            }
        return cls(distributions=out, source=source, model_name=model.name)

    def draw(self, index: int, *, seed: int) -> Any:
        """Participant ``index``'s parameters under run seed ``seed`` (independent of n); for the
        default model a :class:`ParticipantParams`."""
        if index < 0:
            raise PopulationError(f"participant index must be >= 0, got {index}")
        rng = participant_rng(index, seed=seed)
        model = self.model
        sections = {
            section: kind(**{n: d.sample(rng) for n, d in self.distributions[section].items()})
            for section, kind in model.sections.items()
        }
        return model.params(index=index, seed=seed, **sections)

    def typical(self, *, index: int = 0, seed: int = 0) -> Any:
        """A participant with every parameter at its distribution's centre (for tests, demos)."""
        model = self.model
        sections = {
            section: kind(**{n: d.typical for n, d in self.distributions[section].items()})
            for section, kind in model.sections.items()
        }
        return model.params(index=index, seed=seed, **sections)

    def draw_many(self, n: int, *, seed: int) -> list[Any]:
        return [self.draw(i, seed=seed) for i in range(n)]


def _model(data: Mapping[str, Any], source: str) -> UserModel:
    """The model the ``[population]`` table names (``model = "..."``), else the default."""
    meta = data.get("population")
    name = meta.get("model", DEFAULT_MODEL) if isinstance(meta, Mapping) else DEFAULT_MODEL
    if not isinstance(name, str):
        raise PopulationError(f"{source}: population.model must be a model's name, got {name!r}")
    return get_model(name, where=f"{source}: population.model")


def participant_rng(index: int, *, seed: int, stream: int = 0) -> np.random.Generator:
    """The seeded generator of participant ``index``; ``stream`` separates independent uses."""
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence([seed, index, stream])))


def load_population(path: str | Path = DEFAULT_POPULATION_PATH) -> Population:
    """Read and validate a population file."""
    path = Path(path)
    try:
        data = read_bytes_file(path, max_bytes=MAX_POPULATION_BYTES, what="population file")
    except InputFileError as exc:
        raise PopulationError(f"{path}: cannot read population file: it {exc.problem}") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise PopulationError(
            f"{path}: not UTF-8 text (byte offset {exc.start}); re-save it as UTF-8"
        ) from None
    if nesting_depth(text, stop_above=MAX_NESTING)[0] > MAX_NESTING:
        raise PopulationError(f"{path}: values are nested more than {MAX_NESTING} levels deep")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise PopulationError(f"{path}: not valid TOML ({exc})") from exc
    return Population.from_dict(data, source=str(path))
