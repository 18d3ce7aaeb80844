"""The values Dragan & Srinivasa (2013, section 5) report, to print beside ours.

Keys are ``(analysis, effect)`` as used in results.json; ``value`` is the reported statistic
(F, t or r), ``df`` as printed in the paper. Only what the paper states is here.
"""

from __future__ import annotations

PUBLISHED: dict[tuple[str, str], dict[str, object]] = {
    ("timing_ancova", "difficulty"): {"stat": "F", "df": "1, 53", "value": 18.45, "p": "< .001"},
    ("timing_ancova", "correctness"): {"stat": "F", "df": "1, 53", "value": 31.88, "p": "< .001"},
    ("timing_ancova", "mode"): {"stat": "F", "df": "1, 53", "value": 13.2, "p": ".001"},
    ("timing_ancova", "correctness:mode"): {
        "stat": "F",
        "df": "1, 53",
        "value": 36.28,
        "p": "< .001",
    },
    ("timing_ancova", "difficulty:correctness:mode"): {
        "stat": "F",
        "df": "1, 53",
        "value": 2.63,
        "p": ".11",
    },
    ("timing_ancova", "R^2"): {"stat": "R^2", "df": "", "value": 0.66, "p": ""},
    ("timing_effects", "difficulty"): {"stat": "s", "df": "", "value": 22.9, "p": ""},
    ("timing_effects", "correctness"): {"stat": "s", "df": "", "value": 30.1, "p": ""},
    ("timing_effects", "mode"): {"stat": "s", "df": "", "value": 19.4, "p": ""},
    ("timing_mean", "duration_s"): {"stat": "s", "df": "", "value": 28.0, "p": ""},
    ("timing_posthoc", "aggressive&wrong - timid&wrong (aggressive vs timid when wrong)"): {
        "stat": "t",
        "df": "15",
        "value": 7.09,
        "p": "< .001",
    },
    ("timing_planned", "Hard&Right: aggressive - timid"): {
        "stat": "t",
        "df": "7",
        "value": 4.92,
        "p": ".002",
    },
    ("timing_planned", "Easy&Wrong: aggressive - timid"): {
        "stat": "t",
        "df": "7",
        "value": 4.95,
        "p": ".002",
    },
    ("preference", "time_advantage_aggressive"): {
        "stat": "r",
        "df": "30",
        "value": 0.66,
        "p": "< .001",
    },
    ("preference", "ratings"): {"stat": "r", "df": "30", "value": "> .85", "p": "< .001"},
    ("prediction_anova", "predictor"): {
        "stat": "F",
        "df": "1, 112",
        "value": 1020.95,
        "p": "< .001",
    },
    ("prediction_anova", "mode"): {"stat": "F", "df": "1, 112", "value": 7.62, "p": "< .01"},
    ("prediction_anova", "R^2"): {"stat": "R^2", "df": "", "value": 0.9, "p": ""},
}
"""Section 5 of the paper. Signs are not reported for t; compare magnitudes."""


def published(analysis: str, effect: str) -> dict[str, object] | None:
    """The paper's value for one statistic, or None if the paper does not report it."""
    if analysis == "preference" and effect.endswith("_diff"):
        return PUBLISHED[("preference", "ratings")]
    return PUBLISHED.get((analysis, effect))
