"""The three components as FMI 2.0 co-simulation FMUs built with pythonfmu."""
