"""Tools for attitude determination and control (ADCS) software tests.

True motion scenarios (:mod:`.scenarios`), the true attitude (:mod:`.attitude`), several
gyros with truth recording (:mod:`.rig`), fault injection (:mod:`.faults`) and Monte Carlo
runs over noise seeds (:mod:`.montecarlo`). See ``docs/adcs.md``.
"""
