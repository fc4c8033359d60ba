"""Measuring the gap: the windows and the metric on the surrogate (:mod:`.metric`), which data train and which are
held out (:mod:`.split`), the held-out error per log (:mod:`.per_log`), the Drake replay of the headline figures
(:mod:`.replay`) and where the gap lies (:mod:`.localize`). Imports the diagnosis' settings and :mod:`..logs`."""
