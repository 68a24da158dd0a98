"""Diagnosis: find where simulation and recordings disagree, name the missing physics, model it.

>>> report = preisach.diagnose(model, [rec1, rec2, rec3])   # doctest: +SKIP
>>> report.verdict, report.effects[0].statement              # doctest: +SKIP
>>> report.plot(); report.to_json("report.json")             # doctest: +SKIP
>>> report.model.save("augmented.npz")                       # doctest: +SKIP

Modules, bottom to top: :mod:`~preisach.diagnose.effects` (the effect blocks: physics around the
Preisach operator, distinct from the rig's :mod:`preisach.daq.blocks`),
:mod:`~preisach.diagnose.candidates` (candidate explanations), :mod:`~preisach.diagnose.data`
(recordings prepared, noise level), :mod:`~preisach.diagnose.context` (base model, chains,
fitting), :mod:`~preisach.diagnose.problem` (one candidate's training problem),
:mod:`~preisach.diagnose.scoring` (folds, held-out scores, tests),
:mod:`~preisach.diagnose.selection` (forward selection), :mod:`~preisach.diagnose.locate`
(residual analysis), :mod:`~preisach.diagnose.augmented` (the augmented model),
:mod:`~preisach.diagnose.core` (``diagnose``), :mod:`~preisach.diagnose.cli`
(``preisach diagnose``).  The concealed-effect proof lives a layer above, in
:mod:`preisach.studies.diagnosis_cases`.
"""

from __future__ import annotations

from .augmented import AugmentedModel, load_model
from .candidates import Candidate
from .core import diagnose
from .effects import (
    EFFECT_TYPES,
    EffectBlock,
    FeedbackBlock,
    FirstOrderInputLag,
    FirstOrderOutputLag,
    FractionalDelay,
    GainOffset,
    LagrangeDelay,
    LevelDependentGain,
    OutputFeedback,
    PronyCreep,
    RateDependentPlay,
    RateDependentWidth,
    ReversibleRelaxation,
    SecondOrderMode,
    SensorDrift,
    SplineFeedback,
    TwoModes,
)
from .locate import ResidualAnalysis, analyse_residuals
from .registry import CANDIDATES, EFFECTS
from .report import DiagnosisReport, EffectReport

__all__ = [
    "AugmentedModel",
    "EFFECT_TYPES",
    "EffectBlock",
    "FeedbackBlock",
    "CANDIDATES",
    "EFFECTS",
    "Candidate",
    "PronyCreep",
    "DiagnosisReport",
    "FirstOrderInputLag",
    "FirstOrderOutputLag",
    "EffectReport",
    "FractionalDelay",
    "GainOffset",
    "LagrangeDelay",
    "LevelDependentGain",
    "OutputFeedback",
    "RateDependentPlay",
    "RateDependentWidth",
    "ReversibleRelaxation",
    "ResidualAnalysis",
    "SensorDrift",
    "SplineFeedback",
    "SecondOrderMode",
    "TwoModes",
    "analyse_residuals",
    "diagnose",
    "load_model",
]
