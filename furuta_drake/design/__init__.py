"""``furuta-drake design``: the next experiment to run on the rig when a diagnosis' logs cannot decide between
its hypotheses (:func:`~furuta_drake.design.pipeline.design_experiment`,
:func:`~furuta_drake.design.output.write_design`; ``docs/design.md``)."""
