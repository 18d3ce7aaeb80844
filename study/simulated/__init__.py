"""Simulated participants: population parameters, the user model, questionnaire answers, and a
runner that drives them through the real session engine.

- :class:`~study.simulated.models.UserModel`: a simulated-user model, one declaration registered
  in :mod:`study.simulated.models` and named by a population file (default ``interface``: the
  classes below).
- :func:`load_population` / :class:`Population`: parameter distributions (protocols/population.toml)
  and seeded per-participant draws (:class:`ParticipantParams`).
- :class:`SimulatedUser`: an ``app.teleop.InputSource`` for one trial (goal-directed minimum-jerk
  input, reaction delay, noise, steering against a wrong robot, relaxing when helped, grasping);
  with ``goal_level`` it only says where the user wants the handle.
- :class:`~study.simulated.interface.InterfaceUser`: the input a simulated participant gives through the page's gizmo
  handles or held keys (``app.teleop.ParticipantInput``), driven by a goal-level user.
- :class:`QuestionnaireModel`: Likert ratings and preferences from a run's experience.
- :class:`SimulatedParticipant`: one person across a session (input factory + answerer for
  ``study.session.headless.run_headless``).
- :func:`simulate`: enrol and run simulated participants through the real session engine into a
  store (``python -m study simulate``), optionally in worker processes or on a Dask cluster
  (``study.simulated.dask_engine``, one writer merging ``study.simulated.bundle`` bundles).
"""

from study.simulated.errors import PopulationError, SimulationError, SimulationRunError
from study.simulated.experience import RunExperience
from study.simulated.models import UserModel
from study.simulated.participant import SimulatedParticipant
from study.simulated.population import (
    DEFAULT_POPULATION_PATH,
    ParticipantParams,
    Population,
    load_population,
    participant_rng,
)
from study.simulated.questionnaire import QuestionnaireModel
from study.simulated.runner import SimulationReport, simulate
from study.simulated.user_model import SimulatedUser

__all__ = [
    "DEFAULT_POPULATION_PATH",
    "ParticipantParams",
    "Population",
    "PopulationError",
    "QuestionnaireModel",
    "RunExperience",
    "SimulatedParticipant",
    "SimulatedUser",
    "SimulationError",
    "SimulationReport",
    "SimulationRunError",
    "UserModel",
    "load_population",
    "participant_rng",
    "simulate",
]
