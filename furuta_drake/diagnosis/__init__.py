"""Sim-to-real gap diagnosis (``docs/diagnose.md``), a sub-package a stage, each importing only from those before
it in this list:

- :mod:`.settings` (what a diagnosis is told) and :mod:`.formatting` (how a figure is written), shared by all;
- :mod:`.logs`: reading the logs (formats, readers, writers, a run column) into checked ``RunLog``s;
- :mod:`.gap`: measuring the gap (the windows, the train/held-out split, the metric on the surrogate, the Drake
  replay, where the gap lies); :mod:`.result`: the ``Diagnosis`` record the later stages fill;
- :mod:`.selection`: judging effects (the fits and their starts, the sensor's signature, the jitter, the held-out
  rule and the stepwise selection, the torque beyond the list, intervals, detection limits, folds);
- :mod:`.report`: writing the report (files, words, charts, tables);
- :mod:`.pipeline`: ``diagnose`` wires the stages and returns a ``result.Diagnosis``.
"""
