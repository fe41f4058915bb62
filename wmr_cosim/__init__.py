"""wmr-cosim: FMI co-simulation kit for H-infinity control of a wheeled mobile robot.

Sub-packages (each mapped from a top-level folder of the repository):
    wmr_cosim.components   the paper's models in plain Python (components/)
    wmr_cosim.fmus         the FMU slaves and their build (fmus/)
    wmr_cosim.cosim        the generic FMI master (cosim/)
"""
__version__ = "0.1.0"
