"""A Python thread state kept for a thread Python did not start, across its calls into Python.

Basilisk runs each simulation in a C++ thread of its own and calls a Python module's
``UpdateState`` through SWIG, between ``PyGILState_Ensure`` and ``PyGILState_Release``.
CPython keeps no thread state for a thread it did not start, so each such call makes one and
frees it on return; since CPython 3.11 that includes mapping and unmapping a frame stack
(mmap, munmap). Measured on the benchmark's host (``tools/bench_basilisk.py --breakdown``):
8 us per Python module per 5 ms step, where the C++ spacecraft and wheels take 12 us.

``keep_thread_state()``, called from such a call, takes one more ``PyGILState_Ensure``
reference on the thread state the call runs in, so that the state outlives the call: the
next calls from that thread find it (their ``PyGILState_Release`` only releases the GIL),
and every Python module of the simulation runs without the cost (1.3 us for three modules
instead of 24 us). It is Python's own state for that thread, as a thread Python started
has all its life; it is freed with the interpreter, not when the thread ends (CPython frees
a thread state only from its own thread): about 5 kB of memory per simulation run in a
process (a simulation's thread ends when the simulation is deleted).

A thread whose state lasts anyway (the main thread, a ``threading`` thread) is left as it
is. Whether the state lasts is seen, not guessed: a ``threading.local`` value, which lives
in the thread state, is gone at the next call from the same OS thread only when the state
was made anew in between.
"""

from __future__ import annotations

import threading

_this_state = threading.local()  # .lasts: this thread state is known to outlive a call
_seen_threads: set[int] = set()  # native ids of the OS threads that called before


def keep_thread_state() -> bool:
    """Keep the calling thread's Python thread state after this call into Python returns, if
    Python would free it; True when it was kept by this call (once per such thread)."""
    if getattr(_this_state, "lasts", False):
        return False
    _this_state.lasts = True  # outlives the call if the state does
    native = threading.get_native_id()
    if native not in _seen_threads:  # the first call from this thread: its state may last
        _seen_threads.add(native)
        return False
    try:  # the same OS thread, its state made anew: one more reference keeps this one
        import ctypes

        ensure = ctypes.pythonapi.PyGILState_Ensure
    except (ImportError, AttributeError):  # not CPython: nothing to keep
        return False
    ensure()  # the GIL is held by this thread already: a reference count, nothing else
    return True
