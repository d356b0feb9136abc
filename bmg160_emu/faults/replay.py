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
from bmg160_emu.faults.targets import ChipOnBus


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


def replay_bus_fault(entry: dict[str, Any], chip: Any, bus: Any) -> FaultSchedule:
    """A recorded ``corrupt_byte`` acted again: on the next transaction to ``chip`` on
    ``bus`` (the one that followed its entry in the session), with the same byte and bit,
    so the replayed transaction reads, or writes, what the session's did. Writes nothing to
    the bus log; the schedule stays installed, spent, until the replay ends."""
    effect = dict(entry["fault"])
    if effect.get("kind") != "corrupt_byte":
        raise FaultError(f"{effect.get('kind')}: only a corrupt_byte has an entry to replay; a "
                         "failing bus fault is its failed transaction")
    effect.pop("duration_s", None)  # one entry per transaction it touched
    fault = fault_from_dict({**effect, "address": int(chip.address), "max_count": 1},
                            "replayed fault")
    schedule = FaultSchedule([fault], log_to_bus=False)
    schedule.install([ChipOnBus(chip, bus)])
    return schedule
