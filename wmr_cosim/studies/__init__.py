"""Studies of any system: many co-simulations of one base scenario, on a Dask cluster.

* ``sweep_file``: sweep files (grids, random draws) and the points they describe;
* ``metrics``: metrics over recorded variables, and the named sets of metrics an application registers;
* ``system``: what the application says of the system the points run (model names, its judge of a run);
* ``shipment``: what the points read, sent by content to workers that share no file with the driver;
* ``cluster``: the Dask cluster (local, or a scheduler's address);
* ``sweep``: a point in a worker, a set of points, a sweep file run whole;
* ``plots``: the figures of a sweep;
* ``falsification``: the search of a parameter space for the point where a requirement is closest to failing.

Nothing here knows the robot: the application gives the system (``System``) and registers its metric sets
(``register_set``).  This face exports what the rest of the application uses.
"""
from __future__ import annotations

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "cluster": ["Cluster", "check_worker_count", "cluster_options"],
    "falsification": ["falsify", "load_falsification"],
    "metrics": ["MetricSet", "register_set"],
    "sweep": ["run_points", "run_sweep"],
    "sweep_file": ["load_sweep"],
    "system": ["System"],
})
