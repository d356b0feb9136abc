"""File formats as reader/writer pairs: traces, register dumps, rate files."""
