"""The controllers that drive the arm: the LQ state feedback at the upright (paper Sec. IV-A, :mod:`.lqr`) and
the energy swing-up that hands over to it (:mod:`.swingup`). Each is a Drake system with the same ports:
``state_estimate`` in, ``arm_torque_Nm`` out, ``friction_compensation_Nm`` in when compensating."""
