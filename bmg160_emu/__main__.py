"""``python -m bmg160_emu`` is the ``bmg160-emu`` command."""

from bmg160_emu.cli import main

raise SystemExit(main())
