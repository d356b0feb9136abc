"""File formats as readers and writers over common bases, found by kind and suffix in one
registry (io/formats.py): rate records, recordings, replay data, rate streams, rate tables,
traces; register dumps and stand-in declarations by their own readers.

Every format's error derives from :class:`FormatError`, whose message names the file and
the place (io/errors.py).
"""

from bmg160_emu.io.errors import FormatError
from bmg160_emu.io.formats import FileFormat, format_for, read_file, suffixes, write_file

__all__ = ["FileFormat", "FormatError", "format_for", "read_file", "suffixes", "write_file"]
