"""Fault injection for the rigs: :mod:`bmg160_emu.faults`, re-exported here.

The fault kinds and the engine moved below the tools (issue 10) so that script and trace
replay, which act faults too, do not import adcs; this path stays the rigs' public one.
"""

from bmg160_emu.faults import *
from bmg160_emu.faults import __all__  # noqa: F401
