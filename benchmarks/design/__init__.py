"""Does the experiment ``furuta-drake design`` plans settle what the default logs could not, on the project's suite
(``suite.py``), and bring a detection limit down as it predicts, on the independent simulator (``limits.py``)?"""
