"""Does the controller ``furuta-drake tune`` designs from a diagnosis balance better than the nominal design: blind
on the independent simulator (``blind.py``), and beside the limit cycle measured on the real QUBE-Servo 2
(``real.py``)?"""
