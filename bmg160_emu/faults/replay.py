"""Faults of a recorded session acted again: what a trace replay needs from the engine.

Each ``fault:<kind>`` entry of a log (:mod:`bmg160_emu.traffic.fault_entry`) carries the
fault's effect and when it acted; :func:`replay_schedule` turns a session's sample-fault
entries into a schedule that touches exactly the samples they touched.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from bmg160_emu.faults.model import Fault, FaultError, GyroTarget, fault_from_dict
from bmg160_emu.faults.sample_effects import Activation, counts_samples
from bmg160_emu.faults.schedule import FaultSchedule


def replay_schedule(entries: Sequence[dict[str, Any]], target: GyroTarget) -> FaultSchedule:
    """A schedule that acts recorded sample faults again on ``target``, each on exactly the
    samples it touched in the session (same start, end, first sample and held value).

    ``entries`` are the parameters :func:`~bmg160_emu.traffic.fault_entry.parse_fault_entry`
    gives for ``fault:<kind>`` entries of sample faults, in the order of the log. The
    schedule writes nothing to the bus log; install nothing else for these faults.
    """
    faults: list[Fault] = []
    activations: list[Activation] = []
    for entry in entries:
        act = entry.get("activation")
        if not isinstance(act, dict) or act.get("start_s") is None:
            raise FaultError(f"{entry.get('fault')}: the entry does not say when the fault acted")
        fault = fault_from_dict({**entry["fault"], "at_s": float(act["start_s"])}, "replayed fault")
        if fault.layer != "sample":
            raise FaultError(f"{fault.kind} is not a sample fault")
        end = math.inf if act.get("end_s") is None else float(act["end_s"])
        count = fault.samples if counts_samples(fault) else None
        held = None if act.get("held_dps") is None else np.array(act["held_dps"], dtype=float)
        first = -math.inf if act.get("first_sample_s") is None else float(act["first_sample_s"])
        faults.append(fault)
        activations.append(Activation(fault.at_s or 0.0, end, target.index, count, held,
                                      not_before_s=first))
    schedule = FaultSchedule(faults, log_to_bus=False)
    schedule.install_on_samples(target)
    for i, act in enumerate(activations):
        schedule.activate(i, target, act.start_s, activation=act)
    return schedule
