"""Every fault kind on every transfer shape of every Python I2C stack.

A driver reaches the chip through one of many stacks and each sends its own shapes: SMBus
transfers (smbus2, smbus3, FakeSMBus), combined write-then-read I2C_RDWR transfers
(smbus2's i2c_rdwr, periphery, Adafruit_PureIO and Blinka's writeto_then_readfrom,
MicroPython's readfrom_mem, CircuitPython's writeto_then_readfrom), write-only messages and
plain reads from the register pointer. Each shape below reads RANGE..BW (0x0F, 0x10: 0x00,
0x80 after reset) or writes RANGE = 0x02; each fault is armed on the transaction that shape
sends, first as "the next transaction" (bmg160_faults.add without a trigger), then by the
register it names (``on_register``), then by its index (``on_transaction``), and the
test asserts what the driver saw and what the chip holds:

- nack, timeout, stuck_bus: the stack's own error (Linux errno for the /dev/i2c-N stacks;
  MicroPython's and CircuitPython's ENODEV, ETIMEDOUT, EIO for the drop-ins);
- corrupt_byte: a read's byte 1 (BW) arrives with bit 0 inverted (0x81), a write's data
  byte 0 lands inverted (RANGE = 0x03), and a byte the transaction does not carry leaves it
  alone with an event that says so;
- seu, brownout: the chip changed when that transaction came (an upset BW is read as such);
- the sample kinds: activated by that transaction (an onset event naming it).
"""

from __future__ import annotations

import errno
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import pytest
from _stack_drivers import blinka_environment

RANGE, BW, INT_EN_0 = 0x0F, 0x10, 0x15
ADDRESS = 0x68
READ_BACK = bytes([0x00, 0x80])  # RANGE, BW after reset
LINUX = {"nack": errno.EREMOTEIO, "timeout": errno.ETIMEDOUT, "stuck_bus": errno.EBUSY}
MICROPYTHON = {"nack": errno.ENODEV, "timeout": errno.ETIMEDOUT, "stuck_bus": errno.EIO}


@dataclass
class Shape:
    """One transfer shape of one stack: ``run(ctx)`` reads 2 bytes from RANGE (returns
    them) or writes RANGE = 0x02 (returns None); ``names_register``: the transaction names
    RANGE (an ``on_register`` condition can select it); ``setup`` runs before the fault is
    armed (a plain read's register pointer)."""

    stack: str
    name: str
    run: Callable[[Any], bytes | None]
    names_register: bool = True
    setup: Callable[[Any], None] | None = None
    errors: dict[str, int] | None = None

    @property
    def reads(self) -> bool:
        return "read" in self.name

    def __str__(self) -> str:
        return f"{self.stack} {self.name}"


def _smbus_shapes(module_name: str) -> list[Shape]:
    def bus(ctx: Any) -> Any:
        module = __import__(module_name)
        return ctx.keep(module.SMBus(ctx.number))

    def rdwr(ctx: Any, *messages: Any) -> Any:
        module = __import__(module_name)
        bus(ctx).i2c_rdwr(*messages)
        return module

    def combined(ctx: Any) -> bytes:
        module = __import__(module_name)
        get = module.i2c_msg.read(ADDRESS, 2)
        rdwr(ctx, module.i2c_msg.write(ADDRESS, [RANGE]), get)
        return bytes(get)

    def read_message(ctx: Any) -> bytes:
        module = __import__(module_name)
        get = module.i2c_msg.read(ADDRESS, 2)
        rdwr(ctx, get)
        return bytes(get)

    def pointer(ctx: Any) -> None:
        module = __import__(module_name)
        rdwr(ctx, module.i2c_msg.write(ADDRESS, [RANGE]))

    return [
        Shape(module_name, "SMBus word read",
              lambda c: bus(c).read_word_data(ADDRESS, RANGE).to_bytes(2, "little")),
        Shape(module_name, "SMBus i2c block read",
              lambda c: bytes(bus(c).read_i2c_block_data(ADDRESS, RANGE, 2))),
        Shape(module_name, "SMBus byte write", lambda c: bus(c).write_byte_data(ADDRESS, RANGE, 2)),
        Shape(module_name, "i2c_rdwr write-then-read", combined),
        Shape(module_name, "i2c_rdwr write",
              lambda c: rdwr(c, __import__(module_name).i2c_msg.write(ADDRESS, [RANGE, 2]))
              and None),
        Shape(module_name, "i2c_rdwr plain read", read_message, names_register=False,
              setup=pointer),
    ]


def _pureio_shapes() -> list[Shape]:
    def bus(ctx: Any) -> Any:
        from Adafruit_PureIO.smbus import SMBus

        return ctx.keep(SMBus(ctx.number))

    return [
        Shape("PureIO", "read_i2c_block_data (I2C_RDWR) read",
              lambda c: bytes(bus(c).read_i2c_block_data(ADDRESS, RANGE, 2))),
        Shape("PureIO", "write_byte_data (write())", lambda c: bus(c).write_byte_data(
            ADDRESS, RANGE, 2)),
        Shape("PureIO", "read_bytes (read())", lambda c: bytes(bus(c).read_bytes(ADDRESS, 2)),
              names_register=False, setup=lambda c: bus(c).write_byte(ADDRESS, RANGE)),
    ]


def _periphery_shapes() -> list[Shape]:
    def transfer(ctx: Any, messages: list[Any]) -> list[Any]:
        from periphery import I2C

        ctx.keep(I2C(f"/dev/i2c-{ctx.number}")).transfer(ADDRESS, messages)
        return messages

    def message(data: Any, read: bool = False) -> Any:
        from periphery import I2C

        return I2C.Message(data, read=read)

    return [
        Shape("periphery", "transfer write-then-read", lambda c: bytes(transfer(
            c, [message([RANGE]), message(bytearray(2), True)])[1].data)),
        Shape("periphery", "transfer write", lambda c: transfer(c, [message([RANGE, 2])])
              and None),
        Shape("periphery", "transfer plain read", lambda c: bytes(transfer(
            c, [message(bytearray(2), True)])[0].data), names_register=False,
            setup=lambda c: transfer(c, [message([RANGE])]) and None),
    ]


def _busio_shapes(stack: str, i2c: Callable[[Any], Any],
                  errors: dict[str, int] | None = None) -> list[Shape]:
    """The three transfer shapes of a busio.I2C (Blinka's and CircuitPython's alike)."""
    def combined(ctx: Any) -> bytes:
        data = bytearray(2)
        i2c(ctx).writeto_then_readfrom(ADDRESS, bytes([RANGE]), data)
        return bytes(data)

    def plain(ctx: Any) -> bytes:
        data = bytearray(2)
        i2c(ctx).readfrom_into(ADDRESS, data)
        return bytes(data)

    return [
        Shape(stack, "writeto_then_readfrom read", combined, errors=errors),
        Shape(stack, "writeto", lambda c: i2c(c).writeto(ADDRESS, bytes([RANGE, 2])),
              errors=errors),
        Shape(stack, "readfrom_into read", plain, names_register=False,
              setup=lambda c: i2c(c).writeto(ADDRESS, bytes([RANGE])), errors=errors),
    ]


def _blinka_shapes() -> list[Shape]:
    def i2c(ctx: Any) -> Any:
        if "blinka" not in ctx.kept:
            ctx.enter(blinka_environment())
            import board
            import busio

            bus = busio.I2C(board.SCL, board.SDA)
            bus.try_lock()
            ctx.kept["blinka"] = bus
        return ctx.kept["blinka"]

    return _busio_shapes("Blinka busio", i2c)


def _circuitpython_shapes() -> list[Shape]:
    def i2c(ctx: Any) -> Any:
        if "busio" not in ctx.kept:
            board = ctx.fixture("bmg160_circuitpython")
            bus = board.I2C()
            bus.try_lock()
            ctx.kept["busio"] = bus
        return ctx.kept["busio"]

    return _busio_shapes("CircuitPython busio", i2c, errors=MICROPYTHON)


def _machine_shapes() -> list[Shape]:
    def i2c(ctx: Any) -> Any:
        return ctx.fixture("bmg160_machine").I2C(ctx.number)

    return [
        Shape("machine", "readfrom_mem read", lambda c: i2c(c).readfrom_mem(ADDRESS, RANGE, 2),
              errors=MICROPYTHON),
        Shape("machine", "writeto_mem", lambda c: i2c(c).writeto_mem(ADDRESS, RANGE, b"\x02"),
              errors=MICROPYTHON),
        Shape("machine", "writeto", lambda c: i2c(c).writeto(ADDRESS, bytes([RANGE, 2]))
              and None, errors=MICROPYTHON),
        Shape("machine", "readfrom read", lambda c: i2c(c).readfrom(ADDRESS, 2),
              names_register=False, setup=lambda c: i2c(c).writeto(ADDRESS, bytes([RANGE])),
              errors=MICROPYTHON),
    ]


def _fake_smbus_shapes() -> list[Shape]:
    def bus(ctx: Any) -> Any:
        return ctx.fixture("bmg160_fake_smbus")

    return [
        Shape("FakeSMBus", "read_i2c_block_data read",
              lambda c: bytes(bus(c).read_i2c_block_data(ADDRESS, RANGE, 2))),
        Shape("FakeSMBus", "write_byte_data", lambda c: bus(c).write_byte_data(ADDRESS, RANGE, 2)),
    ]


SHAPES = (_smbus_shapes("smbus2") + _smbus_shapes("smbus3") + _pureio_shapes()
          + _periphery_shapes() + _blinka_shapes() + _circuitpython_shapes()
          + _machine_shapes() + _fake_smbus_shapes())

# every kind, with the parameters it needs to show itself
KINDS = {
    "nack": {}, "timeout": {"stall_s": 0.001}, "stuck_bus": {},
    "corrupt_byte": {"bit": 0},  # byte chosen per direction below
    "seu": {"register": BW, "bit": 0}, "brownout": {},
    "stuck_axis": {"axis": "x"}, "bias_step": {"step_dps": 1.0}, "spike": {"amplitude_dps": 5.0},
    "saturation": {"axis": "y"}, "lost_samples": {"samples": 2},
    "temperature_ramp": {"rate_c_per_s": 1.0},
}
TRIGGERS = ("next transaction", "on_register", "on_transaction")
SAMPLE_KINDS = ("stuck_axis", "bias_step", "spike", "saturation", "lost_samples",
                "temperature_ramp")  # conditions select transactions: not for these


class Context:
    """What one test's shape needs: the bus number, fixtures on demand, objects to keep
    and to close, context managers to leave."""

    def __init__(self, request: pytest.FixtureRequest, number: int) -> None:
        self.request, self.number = request, number
        self.kept: dict[str, Any] = {}
        self.exits: list[Any] = []
        self.objects: list[Any] = []

    def fixture(self, name: str) -> Any:
        return self.request.getfixturevalue(name)

    def keep(self, thing: Any) -> Any:
        self.objects.append(thing)
        return thing

    def enter(self, manager: Any) -> None:
        manager.__enter__()
        self.exits.append(manager)

    def close(self) -> None:
        for thing in self.objects:
            close = getattr(thing, "close", None)
            if close is not None:
                close()
        for manager in reversed(self.exits):
            manager.__exit__(None, None, None)


def _cases() -> list[Any]:
    cases = []
    for shape in SHAPES:
        for kind in KINDS:
            for trigger in TRIGGERS:
                if trigger == "on_register" and (not shape.names_register
                                                  or kind in SAMPLE_KINDS):
                    continue  # a plain read names no register; sample faults take none
                if trigger == "next transaction" and kind in SAMPLE_KINDS:
                    continue  # from now on: placed on sample times, not on a transaction
                cases.append(pytest.param(shape, kind, trigger, id=f"{shape}-{kind}-{trigger}"))
    return cases


@pytest.fixture
def context(request, bmg160_smbus):
    ctx = Context(request, bmg160_smbus.number)
    yield ctx
    ctx.close()


@pytest.mark.bmg160(noise=False)
@pytest.mark.parametrize(("shape", "kind", "trigger"), _cases())
def test_the_fault_acts_on_the_shape(shape, kind, trigger, context, bmg160_smbus, bmg160_chip,
                                     bmg160_faults):
    bus, chip = bmg160_smbus, bmg160_chip
    chip.write(INT_EN_0, b"\x40")  # set before: a brown-out takes it back to 0
    if shape.setup is not None:
        shape.setup(context)
    indices: list[int] = []
    bus.transaction_hooks.insert(0, lambda _b, index, _a, _k: indices.append(index))
    params = dict(KINDS[kind])
    if kind == "corrupt_byte":
        params["byte"] = 1 if shape.reads else 0
    if trigger == "on_register":
        params["on_register"] = RANGE
    elif trigger == "on_transaction":
        params["on_transaction"] = (indices[-1] + 1) if indices else _next_index(bus)
    bmg160_faults.add(kind, **params)
    before_events = len(bmg160_faults.events)
    errors = shape.errors or LINUX
    if kind in errors:
        with pytest.raises(OSError) as info:
            shape.run(context)
        assert info.value.errno == errors[kind], (shape, kind, info.value)
        assert bus.log.filter(failed=True), "the failed transaction is in the log"
        return
    result = shape.run(context)
    acting = indices[-1]
    new = bmg160_faults.events[before_events:]
    assert [e.kind for e in new][:1] == [kind], (shape, kind, new)
    assert new[0].transaction == acting
    if kind == "corrupt_byte":
        if shape.reads:
            assert result == bytes([0x00, 0x81]), "byte 1 (BW) heard with bit 0 inverted"
        else:
            assert chip.peek(RANGE) == 0x03, "data byte 0 received with bit 0 inverted"
        assert "0x" in new[0].detail and "not acted" not in new[0].detail
        entries = bus.log.filter(kind="fault:corrupt_byte")
        assert entries and entries[-1].time == new[0].time_s
    elif kind == "seu":
        if shape.reads:
            assert result == bytes([0x00, 0x81]), "the upset came before the read"
        else:
            assert chip.peek(BW) == 0x81
    elif kind == "brownout":
        assert chip.peek(INT_EN_0) == 0x00
    elif shape.reads:
        assert result == READ_BACK


def _next_index(bus: Any) -> int:
    """The index the bus gives its next transaction (none seen yet in this test)."""
    seen: list[int] = []
    hook = lambda _b, index, _a, _k: seen.append(index)
    bus.transaction_hooks.append(hook)
    try:
        bus.write_quick(ADDRESS)  # an ACK, nothing else: counted like any transaction
    finally:
        bus.transaction_hooks.remove(hook)
    return seen[0] + 1


@pytest.mark.bmg160(noise=False)
@pytest.mark.parametrize("shape", [s for s in SHAPES if s.reads], ids=str)
def test_a_corrupt_byte_past_the_bytes_read_says_it_did_not_act(shape, context, bmg160_smbus,
                                                                  bmg160_faults):
    if shape.setup is not None:
        shape.setup(context)
    bmg160_faults.add("corrupt_byte", byte=5, bit=0)
    assert shape.run(context) == READ_BACK
    [event] = bmg160_faults.events
    assert "not acted: the transaction read 2 bytes, no byte 5" in event.detail
