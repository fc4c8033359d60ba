"""Sim-to-real gap diagnosis (``spec/diagnosis-interface.md``): one module a stage, load -> gap -> candidates ->
fit -> select -> localize -> report."""
