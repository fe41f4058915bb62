"""The shipped scenario files (TOML), installed as the package data of ``wmr_cosim.scenarios``.

This folder is the source of truth: edit the files here. An installed ``wmr-cosim`` reads its own copy
(see ``wmr_cosim/scenario_files.py``).
"""
