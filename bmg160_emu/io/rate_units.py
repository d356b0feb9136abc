"""The angular-rate unit of a record's column, from its name or from the user, as deg/s per
unit: identify works in deg/s, and a record in rad/s read as deg/s gives a profile 57.3 times
too quiet that still passes its own verdict (both sides in the same wrong unit).

Public IMU logs name their gyro columns with the unit: the EuRoC MAV and TUM-VI datasets
``w_RS_S_x [rad s^-1]`` (their ``data.csv``), others ``gx_rad_s``, ``gyro_x (deg/s)``,
``x_dps``, ``x_mdps`` (ST's LSM6DS drivers report mdps). A ROS sensor_msgs/Imu message's
``angular_velocity`` is rad/s by its definition, so ``rostopic echo -p``'s
``field.angular_velocity.x`` carries it too. PX4 logs rad/s under bare names (``x``): for
those the user says it (``identify --record-units rad/s``).
"""

from __future__ import annotations

import math
import re

DEG_S_PER_RAD_S = math.degrees(1.0)
# a record's unit as the user names it (identify --record-units)
RECORD_UNITS = {"deg/s": 1.0, "rad/s": DEG_S_PER_RAD_S}
# a unit in brackets or parentheses after the name, spaces removed
_BRACKETED = {
    "deg/s": ("deg/s", 1.0), "degs^-1": ("deg/s", 1.0), "°/s": ("deg/s", 1.0),
    "dps": ("deg/s", 1.0), "mdps": ("mdeg/s", 1e-3), "mdeg/s": ("mdeg/s", 1e-3),
    "rad/s": ("rad/s", DEG_S_PER_RAD_S), "rads^-1": ("rad/s", DEG_S_PER_RAD_S),
    "rad.s^-1": ("rad/s", DEG_S_PER_RAD_S), "rad*s^-1": ("rad/s", DEG_S_PER_RAD_S),
    "rad/sec": ("rad/s", DEG_S_PER_RAD_S), "mrad/s": ("mrad/s", DEG_S_PER_RAD_S * 1e-3),
}
# a unit as the name's last underscore-separated part(s)
_SUFFIXES = {
    "_dps": ("deg/s", 1.0), "_deg_s": ("deg/s", 1.0), "_degps": ("deg/s", 1.0),
    "_mdps": ("mdeg/s", 1e-3), "_rad_s": ("rad/s", DEG_S_PER_RAD_S),
    "_rads": ("rad/s", DEG_S_PER_RAD_S), "_radps": ("rad/s", DEG_S_PER_RAD_S),
}
_UNIT_IN_BRACKETS = re.compile(r"^(.*?)\s*[\[(]([^\[\]()]*)[\])]$")
# sensor_msgs/Imu's angular_velocity (rad/s), as a ROS CSV export names its fields
_ROS_IMU = re.compile(r"^(?:.*\.)?angular_velocity\.([xyz])$")


def rate_unit(name: str) -> tuple[str, str, float] | None:
    """(the name without its unit, the unit, deg/s per unit) when ``name`` carries an
    angular-rate unit, else None."""
    text = name.strip().lower().lstrip("#").strip()
    ros = _ROS_IMU.match(text)
    if ros:
        return ros[1], "rad/s", DEG_S_PER_RAD_S
    found = _UNIT_IN_BRACKETS.match(text)
    if found:
        unit = _BRACKETED.get(found[2].replace(" ", ""))
        return None if unit is None else (found[1], *unit)
    for suffix, unit in _SUFFIXES.items():
        if text.endswith(suffix) and len(text) > len(suffix):
            return (text[: -len(suffix)], *unit)
    return None
