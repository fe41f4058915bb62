"""The co-simulation master on FMPy: generic, knows nothing about robots."""
