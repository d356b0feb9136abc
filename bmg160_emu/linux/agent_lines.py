"""Two more virtio-gpio lines, after the chips' INT lines: the channel between the host and
the guest's agent (bmg160_emu.linux.guest.agent).

Why GPIO lines: the agent must be woken without polling, and under UML time travel every
input to the guest must be an event of the calendar (a virtio interrupt delivered in band);
the virtio-gpio controller already is such a device. The request line is an input of the
guest that the host pulses (a rising edge: "FOLDER/request is written"); the reply line is
an output of the guest, each value it sets is a SET_VALUE request the host sees at once
("FOLDER/response is written"). Requests and replies alternate, so one pulse never stands
for two requests.

The device (:class:`~bmg160_emu.linux.virtio_gpio.VirtioGPIODevice`) answers the lines'
virtio-gpio requests through :meth:`AgentLines.answer`; everything here runs on the back
end's thread.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from bmg160_emu.linux.virtio_gpio_spec import (
    DIRECTION_IN,
    DIRECTION_NONE,
    DIRECTION_OUT,
    IRQ_TYPE_EDGE_RISING,
    IRQ_TYPE_NONE,
    MSG_GET_DIRECTION,
    MSG_GET_VALUE,
    MSG_IRQ_TYPE,
    MSG_SET_DIRECTION,
    MSG_SET_VALUE,
    STATUS_ERR,
    STATUS_OK,
)

REQUEST_NAME = "bmg160-emu-agent-request"
REPLY_NAME = "bmg160-emu-agent-reply"
NAMES = (REQUEST_NAME, REPLY_NAME)



class RequestLine:
    """The guest's input: a rising edge per request (the level reads 0 between pulses)."""

    name = REQUEST_NAME

    def __init__(self) -> None:
        self.irq_type = IRQ_TYPE_NONE
        self.buffer: Any = None  # the guest's event buffer (a virtqueue Chain), while queued
        self.pending = False  # a pulse came while no buffer was queued
        self.interrupts = 0


class AgentLines:
    """The request and reply lines; ``on_reply`` is called at each reply."""

    def __init__(self) -> None:
        self.request = RequestLine()
        self.reply_direction = DIRECTION_NONE
        self.reply_value = 0
        self.replies = 0  # values the guest set on the reply line as an output
        self.on_reply: Callable[[], None] | None = None

    def answer(self, offset: int, kind: int, value: int,
               set_irq_type: Callable[[RequestLine, int], None]) -> bytes:
        """The response to a request for line ``offset`` (0 request, 1 reply)."""
        if offset == 0:
            if kind == MSG_GET_DIRECTION:
                return bytes([STATUS_OK, DIRECTION_IN])
            if kind == MSG_SET_DIRECTION:
                return bytes([STATUS_OK if value in (DIRECTION_IN, DIRECTION_NONE)
                              else STATUS_ERR, 0])
            if kind == MSG_GET_VALUE:
                return bytes([STATUS_OK, 0])
            if kind == MSG_IRQ_TYPE and value in (IRQ_TYPE_NONE, IRQ_TYPE_EDGE_RISING):
                set_irq_type(self.request, value)
                return bytes([STATUS_OK, 0])
            return bytes([STATUS_ERR, 0])
        if kind == MSG_GET_DIRECTION:
            return bytes([STATUS_OK, self.reply_direction])
        if kind == MSG_SET_DIRECTION and value in (DIRECTION_NONE, DIRECTION_IN, DIRECTION_OUT):
            self.reply_direction = value
            return bytes([STATUS_OK, 0])
        if kind == MSG_GET_VALUE:
            return bytes([STATUS_OK, self.reply_value])
        if kind == MSG_SET_VALUE:
            self.reply_value = value & 1
            # gpio-virtio sets the value before the direction when a line becomes an
            # output (virtio_gpio_direction_output): that first value is no reply
            if self.reply_direction == DIRECTION_OUT:
                self.replies += 1
                if self.on_reply is not None:
                    self.on_reply()
            return bytes([STATUS_OK, 0])
        return bytes([STATUS_ERR, 0])
