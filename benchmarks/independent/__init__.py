"""The independent simulator: a Furuta pendulum in numpy and scipy with its own equations of motion and its own
forms of every effect (``simulator.py``), whose logs check the diagnosis, the design and the tuning blind on data
the package was not written from."""
