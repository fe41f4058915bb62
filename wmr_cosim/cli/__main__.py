"""``python -m wmr_cosim.cli``: the ``wmr-cosim`` command."""
from . import entry

entry()
