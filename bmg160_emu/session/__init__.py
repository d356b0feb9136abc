"""The session tools: what a person does with a chip over a session, on the library.

Register scripts and their runner (``script``), recordings of what a driver reads
(``record``), a rate file played as the chip's output (``rate_replay``), a trace replayed
on fresh chips (``trace_replay``) and register and transaction text for people (``decode``). The
``bmg160-emu`` commands of the same names are thin programs on top of them.
"""
