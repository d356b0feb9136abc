"""Tools for attitude determination and control (ADCS) software tests.

True motion scenarios (:mod:`.scenarios`), the true attitude (:mod:`.attitude`), several
gyros with truth recording (:mod:`.rig`), fault injection (:mod:`.faults`) and Monte Carlo
runs over noise seeds (:mod:`.montecarlo`). See ``docs/adcs.md``.
"""

from bmg160_emu.adcs.attitude import integrate_attitude
from bmg160_emu.adcs.montecarlo import run_montecarlo
from bmg160_emu.adcs.rig import GyroRig, GyroSpec, Truth
from bmg160_emu.adcs.scenarios import Scenario, ScenarioError, load_scenario
from bmg160_emu.faults import Fault, FaultSchedule

__all__ = [
    "Fault",
    "FaultSchedule",
    "GyroRig",
    "GyroSpec",
    "Scenario",
    "ScenarioError",
    "Truth",
    "integrate_attitude",
    "load_scenario",
    "run_montecarlo",
]
