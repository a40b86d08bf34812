"""dss14-env: calibrated model and Gymnasium environment of the DSS-14 antenna servo.

The model follows W. Gawronski and R. Bartos, "Modeling and Analysis of the DSS-14 Antenna
Control System", JPL TDA Progress Report 42-124 (1996), called [R] in the docstrings.
"""

__version__ = "0.1.0"
