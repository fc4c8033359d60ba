"""The paper's observers and the closed loop on the real QUBE-Servo 2 runs (``furuta-drake reproduce --only
real``): which run plays which part (:mod:`.runs`), the observers on measured data (:mod:`.observers_study`), the
real against the simulated closed loop before and after the diagnosis' correction (:mod:`.closed_loop_study`),
and their report (:mod:`.report`)."""
