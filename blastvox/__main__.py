"""``python -m blastvox`` is the ``blastvox`` command."""

from blastvox.cli.entry import main

main()
