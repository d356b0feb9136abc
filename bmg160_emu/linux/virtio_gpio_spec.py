"""The virtio-gpio device's wire values (virtio 1.2, 5.18): the feature bit, the request
types (5.18.6), the response statuses, the line directions, the interrupt trigger types
and the interrupt event statuses (5.18.6.2). One table for the device
(:mod:`bmg160_emu.linux.virtio_gpio`) and the agent's lines it serves
(:mod:`bmg160_emu.linux.agent_lines`)."""

from __future__ import annotations

VIRTIO_GPIO_F_IRQ = 0
MSG_GET_NAMES = 0x0001
MSG_GET_DIRECTION = 0x0002
MSG_SET_DIRECTION = 0x0003
MSG_GET_VALUE = 0x0004
MSG_SET_VALUE = 0x0005
MSG_IRQ_TYPE = 0x0006
STATUS_OK = 0
STATUS_ERR = 1
DIRECTION_NONE = 0
DIRECTION_OUT = 1
DIRECTION_IN = 2
IRQ_TYPE_NONE = 0x00
IRQ_TYPE_EDGE_RISING = 0x01
IRQ_TYPE_EDGE_FALLING = 0x02
IRQ_TYPE_EDGE_BOTH = 0x03
IRQ_TYPE_LEVEL_HIGH = 0x04
IRQ_TYPE_LEVEL_LOW = 0x08
IRQ_TYPES = (IRQ_TYPE_NONE, IRQ_TYPE_EDGE_RISING, IRQ_TYPE_EDGE_FALLING, IRQ_TYPE_EDGE_BOTH,
             IRQ_TYPE_LEVEL_HIGH, IRQ_TYPE_LEVEL_LOW)
IRQ_STATUS_INVALID = 0
IRQ_STATUS_VALID = 1
