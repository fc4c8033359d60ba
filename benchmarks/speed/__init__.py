"""Time and memory: of the diagnosis per case, on a long log and on trial tables; of its compiled surrogate and
exact sensitivities against their references; of the closed-loop simulation against its C++ floor and a scipy
peer; of an unmodelled torque in a simulation; of a parameter sweep on one and two Dask workers."""
