"""``furuta-drake tune``: from a diagnosis to a controller for the rig (``docs/tune.md``).

The corrected model (the rig file with the diagnosis' accepted effects) is linearized by Drake at the upright
and sampled at the rig's period with the fitted delay and lag as states (:mod:`.design`); the LQ gain on
[theta, phi, theta_dot, phi_dot] is designed on it, the observer and the Dahl friction observer are set from the
fitted friction (:mod:`.controller`), and the candidates are simulated in Drake on the corrected model
(:mod:`.predict`, figures by :mod:`.limit_cycle`), judged by their margins (:mod:`.margins`) and over the
parameters' 95 % intervals (:mod:`.robustness`); :mod:`.pipeline` runs them, :mod:`.output` writes the files.
"""
