"""File formats as reader/writer pairs: traces, register dumps, rate files.

Every format's error derives from :class:`FormatError`; :func:`format_for` finds the
reader and writer of a file by its suffix (``io.rates`` registers .csv, .npz and .npy).
"""

from bmg160_emu.io.errors import FileFormat, FormatError, format_for, register_format, suffixes

__all__ = ["FileFormat", "FormatError", "format_for", "register_format", "suffixes"]
