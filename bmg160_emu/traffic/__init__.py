"""Bus traffic as every front end, file and tool records it, below the buses and the files.

Why its own floor: the in-process buses (``bmg160_emu.bus``) write these records, the trace
files (``bmg160_emu.io.trace``) read and write them, the fault engine (``bmg160_emu.faults``)
adds entries to them and the session tools replay them; none of those should import
another to learn what a transaction is (python-can keeps its ``Message`` below both its
buses and its log formats for the same reason).

- :mod:`.transaction`: ``Transaction`` (one transaction as the host saw it) and
  ``TransactionLog`` (a bus's log, what a test asserts on);
- :mod:`.kinds`: the transaction kinds in smbus2's words, the adapter functionality each
  needs (``KIND_FUNCS``), and what each does on the wire, whichever stack sent it;
- :mod:`.fault_entry`: the ``fault:<kind>`` entries a fault schedule adds to a log, written
  and read in one place.
"""
