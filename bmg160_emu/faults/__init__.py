"""Fault injection for robustness tests: what can go wrong with a gyro on a spacecraft bus.

The kinds and their parameters are :mod:`.model`, the engine that acts them :mod:`.schedule`
(a sample fault's effect on one sample :mod:`.sample_effects`; the targets outside a rig and
the chip calls faults make :mod:`.targets`), a log's faults acted again :mod:`.replay`, one
fault into one chip :mod:`.inject`; this package exports them (``bmg160_emu.adcs.faults``
re-exports it for the rigs).

A :class:`FaultSchedule` is a list of :class:`Fault` entries, each a *trigger* (at time
``at_s``, on the bus's ``on_transaction``-th transaction, or with ``probability`` per
transaction, drawn from the schedule's seed) and an *effect*:

| kind | layer | effect |
| --- | --- | --- |
| ``nack`` | bus | the transaction fails with ``OSError(EREMOTEIO)`` (121), as a NACK does |
| ``timeout`` | bus | the transaction fails with ``OSError(ETIMEDOUT)`` (110) after ``stall_s`` |
| ``stuck_bus`` | bus | every transaction on the bus fails with ``OSError(EBUSY)`` (16) for ``duration_s`` (None: for ever), as while a device holds SDA low |
| ``corrupt_byte`` | bus | bit ``bit`` of the ``byte``-th byte the host reads is inverted (with PEC: EBADMSG), or on a write-only transaction of the ``byte``-th data byte the chip stores |
| ``stuck_axis`` | sample | ``axis`` repeats its last value for ``duration_s`` (None: for ever) |
| ``bias_step`` | sample | ``step_dps`` added to ``axis`` (or to all axes) from then on |
| ``spike`` | sample | ``amplitude_dps`` added to ``axis`` for ``samples`` output samples |
| ``saturation`` | sample | ``axis`` at full scale (sign of ``amplitude_dps``) for ``duration_s`` |
| ``lost_samples`` | sample | ``samples`` output periods without a new sample (no data-ready) |
| ``seu`` | chip | bit ``bit`` of register ``register`` flips (single-event upset) |
| ``brownout`` | chip | spontaneous reset: every register back to its reset value |
| ``temperature_ramp`` | sample | die temperature rises by ``rate_c_per_s`` for ``duration_s``, the bias follows with ``tc_bias_dps_per_c`` |

Bus faults act in ``I2CBus.transaction_hooks``, sample faults in ``BMG160.sample_hooks`` (the
rate in the sensor frame, deg/s, before scaling to counts), chip faults between two
transactions. Every onset is a :class:`FaultEvent` in :attr:`FaultSchedule.events`; a bus
fault is the failed transaction itself in the bus's transaction log, any other fault adds a
``fault:<kind>`` entry there (a chip fault when it acts, a sample fault at the first sample
it touches): its description, then a JSON line of what it did
(:mod:`bmg160_emu.traffic.fault_entry`),
from which a trace replay acts it again (:func:`replay_schedule`); every output sample a
fault touched carries its :data:`FAULT_FLAGS` bit in the rig's truth record, and a bus or
chip fault flags the gyro's next output sample.

Conditions: ``address`` (a 7-bit address) and ``on_register`` (the register a transaction
names) restrict a fault to the transactions that meet them; alone, without a trigger, they
select the first such transaction.

Triggers: ``at_s`` acts exactly at that time for sample faults and at the first transaction
at or after it for bus and chip faults; ``on_transaction`` counts the transactions of the
target gyro's bus as the bus numbers them; ``probability`` is drawn once per transaction
on that bus (per transaction addressed to the gyro for bus faults) from a random stream
that depends only on the schedule's seed and the fault's place in the list.
"""

from bmg160_emu.faults.inject import inject
from bmg160_emu.faults.model import (
    AXES,
    BUS_KINDS,
    CHIP_KINDS,
    FAULT_FLAGS,
    FAULT_KINDS,
    SAMPLE_KINDS,
    SATURATED_DPS,
    Fault,
    FaultError,
    FaultEvent,
    GyroTarget,
    describe_flags,
    fault_from_dict,
)
from bmg160_emu.faults.replay import replay_bus_fault, replay_schedule
from bmg160_emu.faults.schedule import FaultSchedule
from bmg160_emu.faults.targets import ChipOnBus

__all__ = [
    "AXES", "BUS_KINDS", "CHIP_KINDS", "FAULT_FLAGS", "FAULT_KINDS", "SAMPLE_KINDS",
    "SATURATED_DPS", "ChipOnBus", "Fault", "FaultError", "FaultEvent", "FaultSchedule", "GyroTarget",
    "describe_flags", "fault_from_dict", "inject", "replay_bus_fault", "replay_schedule",
]
