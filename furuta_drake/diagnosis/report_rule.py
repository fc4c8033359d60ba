"""The acceptance rule's constants as the report shows them, read from :mod:`~furuta_drake.diagnosis.select`
(never retyped), each with what it decides."""

from __future__ import annotations

from furuta_drake.diagnosis.formatting import percent
from furuta_drake.diagnosis.select import CLOSES, CONFUSABLE_LEVEL, ENTRY, FLOOR_COUNTS, MARGIN, PARSIMONY

RULE_CONSTANTS = (
    ("FLOOR_COUNTS", f"{FLOOR_COUNTS} counts", "a held-out gap below it is at the encoder floor: nothing more enters"),
    ("ENTRY", percent(ENTRY), "a candidate enters when the 5 % lower bound of its reduction exceeds it"),
    ("PARSIMONY", percent(PARSIMONY), "a candidate with fewer parameters within it of the best is preferred"),
    (
        "MARGIN",
        percent(MARGIN),
        "an effect is kept when it reduces the gap of the model holding the others by at least this",
    ),
    ("CLOSES", percent(CLOSES), "accepted effects reducing the nominal gap by less than this leave it unexplained"),
    (
        "CONFUSABLE_LEVEL",
        percent(CONFUSABLE_LEVEL),
        "two candidates whose difference of reductions has an interval of this level holding 0 are confusable",
    ),
)
