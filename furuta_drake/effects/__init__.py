"""The effect model, below the rig file, the diagnosis and the experiment design that all use it: the effect
vocabulary and its forms (:mod:`.vocabulary`), the batched surrogate of the Furuta pendulum with those effects
(:mod:`.surrogate`, its compiled RK4 kernel :mod:`.surrogate_kernel`), and a model with effects as the Drake
world's parameters, a simulate config and a rig file (:mod:`.corrected`)."""
