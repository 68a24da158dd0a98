"""The registry of diagnosis candidates: every explanation `diagnose` tests.

The candidate classes live in :mod:`.candidates` (the classical forms and the general linear
block) and :mod:`.rate_family` (the rate-dependent Everett family, which subclasses
:class:`~.candidates.Candidate`); this module names them all, so neither imports the other's
list.
"""

from __future__ import annotations

from .candidates import (
    Candidate,
    CreepCandidate,
    DelayCandidate,
    DriftCandidate,
    GainOffsetCandidate,
    LagrangeDelayCandidate,
    ModeCandidate,
    ModeReactionCandidate,
    NonCongruenceCandidate,
    OutputCurveCandidate,
    OutputLagCandidate,
    RateCandidate,
    RateLagCandidate,
    RateWidthCandidate,
    RelaxationCandidate,
    TwoModesCandidate,
    ViscousCandidate,
)
from .rate_family import RateFamilyCandidate

__all__ = ["CANDIDATES", "EFFECTS", "default_candidates"]

#: The candidate classes by effect name.
CANDIDATES: dict[str, type[Candidate]] = {
    c().key: c
    for c in (
        RateLagCandidate,
        RateCandidate,
        RateWidthCandidate,
        RateFamilyCandidate,
        RelaxationCandidate,
        ViscousCandidate,
        ModeCandidate,
        ModeReactionCandidate,
        TwoModesCandidate,
        CreepCandidate,
        DelayCandidate,
        LagrangeDelayCandidate,
        OutputLagCandidate,
        DriftCandidate,
        NonCongruenceCandidate,
        GainOffsetCandidate,
        OutputCurveCandidate,
    )
}

#: Effect names (several candidates may test forms of the same effect).
EFFECTS: tuple[str, ...] = tuple(dict.fromkeys(c.name for c in CANDIDATES.values()))


def default_candidates() -> list[Candidate]:
    """One instance of every candidate."""
    return [c() for c in CANDIDATES.values()]
