"""The paper's calibration of its two arbitration modes, on simulated participants.

``python -m study sweep`` runs a grid of arbitration settings (:mod:`study.sweep.grid`; and with
``--confidence-D`` the protocol's own two modes at other ``D`` of the distance confidence) through
simulated participants (:func:`study.simulated.simulate`, local or Dask engine), judges each by
the paper's two criteria with stated thresholds (:mod:`study.sweep.criteria`), and writes a table,
a figure, the evidence and the chosen parameters as a protocol snippet (:mod:`study.sweep.report`).
"""

from study.sweep.criteria import Criteria, Measure, choose, measure
from study.sweep.errors import SweepError, SweepGridError, SweepProtocolError
from study.sweep.grid import aggressive, current_settings, make_grid, timid, variant_text
from study.sweep.run import SweepResult, sweep

__all__ = [
    "Criteria",
    "Measure",
    "SweepError",
    "SweepGridError",
    "SweepProtocolError",
    "SweepResult",
    "aggressive",
    "choose",
    "current_settings",
    "make_grid",
    "measure",
    "sweep",
    "timid",
    "variant_text",
]
