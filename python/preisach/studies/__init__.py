"""Studies: proof harnesses that sit a layer above what they prove.

:mod:`~preisach.studies.diagnosis_cases` makes concealed-effect case folders and runs
diagnosis on them (the proof of :mod:`preisach.diagnose`); it may import everything below it
(identification, the virtual rig, diagnosis), and nothing below imports it.
"""
