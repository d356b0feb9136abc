"""``bmg160-emu watch``: a live terminal view of a running session (docs/commands/watch.md).

``session`` is the watched side (a Unix socket in a private directory); ``view`` draws the
snapshots with rich. Only ``view`` needs rich, so a session can be watchable without it.
"""
