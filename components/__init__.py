"""The paper's physics and algorithms as plain-Python components, free of any FMI import.

Modules:
    paper        the paper's printed constants and results (Tables 1-3), loaded from paper_results.json
    validation   one-line parameter errors
    params       each parameter's facts (unit, check, meaning, tunable) declared once, in its dataclass field
    friction     the friction law (36) and the foam's friction change
    plant        Maggi dynamics (34)-(36) of the drive wheels and the pose of point A (23)-(24), RK4
    sensor       quantised encoders, increment velocity (42), filter (43), wheel angle
    planner      velocity profile (50), go-to-goal kinematic control (26)-(32), straight-line task
    critic       the ADP H-infinity critic (45)-(51) and its two players
    controller   odometry + planner + critic: the controller of Fig. 4 / Fig. 10
    direct_loop  the three components wired together without FMI (the reference and speed baseline)
    metrics      RMSE (54) and the other figures of the paper's tables

Every module uses relative imports only, so that the whole folder can be bundled inside an FMU
under another package name.
"""
