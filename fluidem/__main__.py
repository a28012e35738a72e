"""``python -m fluidem`` is the same as the ``fluidem`` command."""

from fluidem.cli import main

raise SystemExit(main())
