"""Questionnaire answers: tied to time and to how much the robot overrode the participant."""

from __future__ import annotations

import numpy as np

from study.simulated import QuestionnaireModel, RunExperience, load_population, participant_rng

TRAINING = [RunExperience(duration_s=d, mean_disagreement=0.05, success=True) for d in (9, 8, 7)]


def models(n: int, *, seed: int = 4) -> list[QuestionnaireModel]:
    pop = load_population()
    out = []
    for i in range(n):
        q = QuestionnaireModel(
            pop.draw(i, seed=seed).questionnaire, rng=participant_rng(i, seed=seed, stream=9)
        )
        q.observe_training(TRAINING)
        out.append(q)
    return out


def test_answers_are_on_the_scale() -> None:
    q = models(1)[0]
    awful = RunExperience(duration_s=500.0, mean_disagreement=1.0, success=False)
    great = RunExperience(duration_s=0.5, mean_disagreement=0.0, success=True)
    for run in (awful, great):
        answers = q.rate(["helpful", "matched", "teammate", "other"], run, points=7)
        assert set(answers.values()) <= set(range(1, 8))
    assert q.rate(["helpful"], awful, points=5)["helpful"] == 1
    assert q.rate(["helpful"], great, points=5)["helpful"] == 5
    assert 1 <= q.prefer(awful, great, points=7) <= 7


def test_ratings_fall_with_time() -> None:
    rng = np.random.default_rng(0)
    durations, ratings = [], []
    for q in models(60):
        for _ in range(4):
            d = float(np.exp(rng.uniform(np.log(5), np.log(80))))
            run = RunExperience(duration_s=d, mean_disagreement=0.1, success=True)
            durations.append(np.log(d))
            ratings.append(q.rate(["helpful"], run, points=7)["helpful"])
    r = np.corrcoef(durations, ratings)[0, 1]
    assert r < -0.6


def test_preference_follows_the_time_difference() -> None:
    rng = np.random.default_rng(1)
    diffs, prefs = [], []
    for q in models(60):
        t1, t2 = (float(x) for x in rng.uniform(6, 60, size=2))
        first = RunExperience(duration_s=t1, mean_disagreement=0.1, success=True)
        second = RunExperience(duration_s=t2, mean_disagreement=0.1, success=True)
        diffs.append(np.log(t2 / t1))
        prefs.append(q.prefer(first, second, points=7))
    # 1 = the first run, 7 = the second: a slower second run pushes the answer toward 1
    assert np.corrcoef(diffs, prefs)[0, 1] < -0.6


def test_being_overridden_lowers_match_and_preference() -> None:
    calm = RunExperience(duration_s=10.0, mean_disagreement=0.05, success=True)
    fought = RunExperience(duration_s=10.0, mean_disagreement=0.5, success=True)
    qs = models(40)
    matched_calm = np.mean([q.rate(["matched"], calm, points=7)["matched"] for q in qs])
    matched_fought = np.mean([q.rate(["matched"], fought, points=7)["matched"] for q in qs])
    assert matched_calm > matched_fought + 1.0
    prefs = [q.prefer(fought, calm, points=7) for q in qs]
    assert np.mean(prefs) > 5.0


def test_control_bias_makes_disagreement_weigh_more() -> None:
    pop = load_population()
    base = pop.typical().questionnaire
    import dataclasses

    loves_control = dataclasses.replace(base, control_bias=1.0, noise_sd=0.0)
    indifferent = dataclasses.replace(base, control_bias=-0.8, noise_sd=0.0)
    # the second run was faster but the robot overrode them more
    slow_own = RunExperience(duration_s=20.0, mean_disagreement=0.05, success=True)
    fast_overridden = RunExperience(duration_s=10.0, mean_disagreement=0.35, success=True)
    answers = {}
    for name, params in (("control", loves_control), ("indifferent", indifferent)):
        q = QuestionnaireModel(params, rng=np.random.default_rng(0))
        q.observe_training(TRAINING)
        answers[name] = q.prefer(slow_own, fast_overridden, points=7)
    assert answers["control"] < 4 < answers["indifferent"]


def test_helpfulness_ignores_the_control_bias() -> None:
    import dataclasses

    base = load_population().typical().questionnaire
    runs = RunExperience(duration_s=8.0, mean_disagreement=0.4, success=True)
    out = []
    for bias in (-0.8, 1.5):
        q = QuestionnaireModel(
            dataclasses.replace(base, control_bias=bias, noise_sd=0.0),
            rng=np.random.default_rng(0),
        )
        q.observe_training(TRAINING)
        out.append(q.rate(["helpful", "teammate"], runs, points=7))
    assert out[0]["helpful"] == out[1]["helpful"]
    assert out[0]["teammate"] > out[1]["teammate"]
