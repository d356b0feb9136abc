"""Static rate records for identification: read by the one rate-file reader.

The reading moved to :mod:`bmg160_emu.io.rates` (issue 10: one reader for every time + rate
file, one error type); the names stay here for the code that imports them from noise.
"""

from bmg160_emu.io.rates import (
    GAP_FACTOR,
    RATE_COLUMN_SETS,
    TIME_COLUMN_NAMES,
    RateFileError,
    RateRecord,
    load_rate_record,
)

RecordError = RateFileError  # the one rate-file error; the old name stays

__all__ = ["GAP_FACTOR", "RATE_COLUMN_SETS", "TIME_COLUMN_NAMES", "RateRecord", "RecordError",
           "load_rate_record"]
