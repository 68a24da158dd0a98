"""Diagnosis: find where simulation and recordings disagree, name the missing physics, model it.

>>> report = preisach.diagnose(model, [rec1, rec2, rec3])   # doctest: +SKIP
>>> report.verdict, report.effects[0].statement              # doctest: +SKIP
>>> report.plot(); report.to_json("report.json")             # doctest: +SKIP
>>> report.model.save("augmented.npz")                       # doctest: +SKIP

Modules: :mod:`~preisach.diagnose.blocks` (the physics blocks), :mod:`~preisach.diagnose.candidates`
(candidate explanations), :mod:`~preisach.diagnose.locate` (residual analysis),
:mod:`~preisach.diagnose.engine` (fitting, held-out scoring, forward selection),
:mod:`~preisach.diagnose.augmented` (the augmented model), :mod:`~preisach.diagnose.cases`
(concealed-effect test cases), :mod:`~preisach.diagnose.cli` (``preisach diagnose``).
"""

from __future__ import annotations

from .augmented import AugmentedModel, load_model
from .blocks import (
    BLOCK_TYPES,
    Block,
    Creep,
    FirstOrderInputLag,
    FractionalDelay,
    GainOffset,
    LevelDependentGain,
    OutputFeedback,
    RateDependentPlay,
    RateDependentWidth,
    SensorDrift,
    StructuralMode,
)
from .candidates import CANDIDATES, EFFECTS, Candidate
from .core import diagnose
from .locate import ResidualAnalysis, analyse_residuals
from .report import DiagnosisReport, EffectReport

__all__ = [
    "AugmentedModel",
    "BLOCK_TYPES",
    "Block",
    "CANDIDATES",
    "EFFECTS",
    "Candidate",
    "Creep",
    "DiagnosisReport",
    "FirstOrderInputLag",
    "EffectReport",
    "FractionalDelay",
    "GainOffset",
    "LevelDependentGain",
    "OutputFeedback",
    "RateDependentPlay",
    "RateDependentWidth",
    "ResidualAnalysis",
    "SensorDrift",
    "StructuralMode",
    "analyse_residuals",
    "diagnose",
    "load_model",
]
