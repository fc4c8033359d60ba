"""Does ``furuta-drake diagnose`` name the effects a rig has, and how far can its report be trusted?

The blind suites: the project's own, recorded in Drake with hidden effects (``suite.py`` writes its cases,
``confusion.py`` scores them), and the independent simulator's (``independent.py``); both run their cases on Dask
(``shards.py``) and write a verdict table that ``verdict_table.py`` joins and compares with an earlier run. Beside
them, the checks of what a report states (detection limits, parameter intervals, the torque beyond the vocabulary),
of logs as labs record them (low rates, bang-bang commands, velocity columns, geared drives, real logs with a known
effect written in), of finishing on any valid logs, and of the report as a browser shows it."""
