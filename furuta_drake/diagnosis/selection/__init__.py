"""Judging effects: a candidate's fit with its starts and intervals (:mod:`.fit`, :mod:`.equation_error`,
:mod:`.jumps`, :mod:`.jitter_fit`), the sensor's signature (:mod:`.sensor`), the held-out rule and its thresholds
(:mod:`.rule`) stepped by :mod:`.stepwise`, the torque beyond the vocabulary (:mod:`.missing_torque`, selected
again beside it by :mod:`.reselection`), the accepted model refitted (:mod:`.final_fit`) with intervals that hold
beside a rival (:mod:`.rival`), detection limits (:mod:`.detection`) and the folds of ``--folds`` (:mod:`.folds`).
Imports :mod:`..logs`, :mod:`..gap`, :mod:`..result` and the shared settings and formatting."""
