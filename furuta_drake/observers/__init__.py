"""The paper's observers: high-gain (Eq. 4-6), Dahl friction (Eq. 8-9, 16), velocity and friction error (Eq. 11-13)."""
