"""The chips behind a socket any simulator can speak to (``bmg160-emu serve``).

``protocol`` is the versioned wire format (docs/serve-protocol.md), ``session`` one
simulator's board and its requests, ``server`` the loop that serves every client, and
``client`` a Python client of it. The Zephyr module in the repository's ``zephyr/`` folder
has a C client in its native_sim host half.
"""
