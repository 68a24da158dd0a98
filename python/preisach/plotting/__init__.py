"""Every figure of :mod:`preisach` in one place: each returns the Figure, none calls show().

Axes are labelled with units: inputs alpha, beta, r, s and u in volts (V), outputs y in volts
(V), time in seconds (s), rates in V/s, the weight density in V/V^2, kappa in V/V, control
effort in DAQ volts.  Every ``.plot()`` method of a result delegates to a function here, so
``preisach.plotting`` is where users find them all (identification figures live in
:mod:`preisach.identify.plots` and are re-exported unchanged):

Preisach model (chapter 2)
    :func:`plot_major_loop` (major loop and FOD curves), :func:`plot_simulation`,
    :func:`plot_boundary` (the Preisach plane with P+ / P- and the boundary psi of a state, in
    (alpha, beta) or (r, s)), :func:`plot_everett` (the Everett function E as a surface in
    (alpha, beta) or (r, s)).
Identification (chapter 3, from :mod:`preisach.identify.plots`)
    :func:`plot_fod_data` (Figs 3.18-3.20), :func:`plot_fod_surface` (Figs 3.30-3.35),
    :func:`plot_forc_diagram` (a magnetometer FORC diagram),
    :func:`plot_weights` (the density of mu, Figs 3.36-3.44), :func:`plot_kappa` (Figs 3.37,
    3.39, 3.41), :func:`plot_cv`, :func:`plot_identification` (six panels of an
    identification report) and :func:`plot_verification` (Figs 3.48, 3.52, 3.56).
Neutral states and regulation (chapters 4-5, from :mod:`preisach.neutral` and
:mod:`preisach.experiments`)
    :func:`plot_neutral_locus` (N(l) over the major loop with psi_n, psi_a, psi_d marked,
    Figs 4.6-4.8; :func:`plot_locus` draws a computed locus, ``NeutralLocus.plot``),
    :func:`plot_trial` (one drift or PI trial, Figs 4.9-4.11 / 5.2-5.4:
    :func:`plot_drift_trial`, :func:`plot_closed_loop_trial`), :func:`plot_sweep` (what
    ``SweepResult.plot`` draws),
    :func:`plot_drift_summary` (Fig 4.12), :func:`plot_effort_summary` (Figs 5.5-5.7),
    :func:`plot_effort_increase` (Table 5.1 as a figure), :func:`plot_paired_differences`,
    :func:`plot_sweep_traces`, :func:`plot_initial_states`.
Rate-dependent model (:mod:`preisach.rate_model`)
    :func:`plot_rate_loops` (major loops across sweep rates), :func:`plot_everett_across_rates`
    (the blended Everett function at several rates), :func:`plot_loop_width` (loop width
    against rate, model and data).
Diagnosis (:mod:`preisach.diagnose`)
    :func:`plot_residual_map` (mean residual over input level and input rate, and along the
    loop) and :func:`plot_diagnosis` (residual maps, spectra and the held-out fit of a
    :class:`~preisach.DiagnosisReport`).
"""

from __future__ import annotations

from ..identify.plots import (
    plot_cv,
    plot_fod_data,
    plot_fod_surface,
    plot_forc_diagram,
    plot_kappa,
    plot_verification,
    plot_weights,
)
from ..identify.plots import plot_report as plot_identification
from .diagnose import plot_diagnosis, plot_residual_map
from .experiments import (
    plot_closed_loop_trial,
    plot_drift_summary,
    plot_drift_trial,
    plot_effort_increase,
    plot_effort_summary,
    plot_initial_states,
    plot_locus,
    plot_neutral_locus,
    plot_paired_differences,
    plot_sweep,
    plot_sweep_traces,
    plot_trial,
)
from .model import (
    boundary_polyline,
    fod_sweep_input,
    plot_boundary,
    plot_everett,
    plot_major_loop,
    plot_simulation,
)
from .rate import plot_everett_across_rates, plot_loop_width, plot_rate_loops

__all__ = [
    "boundary_polyline",
    "fod_sweep_input",
    "plot_boundary",
    "plot_closed_loop_trial",
    "plot_cv",
    "plot_diagnosis",
    "plot_drift_summary",
    "plot_drift_trial",
    "plot_effort_increase",
    "plot_effort_summary",
    "plot_everett",
    "plot_everett_across_rates",
    "plot_fod_data",
    "plot_fod_surface",
    "plot_forc_diagram",
    "plot_identification",
    "plot_initial_states",
    "plot_kappa",
    "plot_locus",
    "plot_loop_width",
    "plot_major_loop",
    "plot_neutral_locus",
    "plot_paired_differences",
    "plot_rate_loops",
    "plot_residual_map",
    "plot_simulation",
    "plot_sweep",
    "plot_sweep_traces",
    "plot_trial",
    "plot_verification",
    "plot_weights",
]
