"""The paper's experiments through our FMUs, and what we measure beyond them.

* ``tasks``: the tasks file (which protocol file runs each of the paper's tasks);
* ``job``: the paper job (``wmr-cosim paper``): every task, analysed, reported;
* ``analysis``: Tables 2 and 3's figures from recorded runs, divergence, the disturbance analysis;
* ``robot_measures``: what a point of a study measures of the robot's runs (its registered metric set);
* ``gamma``: the suboptimal H-infinity gamma of section 2.1, by grid and bisection;
* ``robustness``: the whole protocol under mismatch, heading, noise and bumps;
* ``figures``: Figures 5-9 and 11-13 redrawn;
* ``claims``, ``report``, ``document``: the report's pass/fail statements, its blocks, its Markdown and HTML.

This face exports what the command line uses.
"""
from __future__ import annotations

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "gamma": ["gamma_search"],
    "analysis": ["judge_run"],
    "job": ["exit_code", "run_paper", "unfinished_runs"],
    "robot_measures": ["robot_system"],
})
