"""``python -m blastvox`` is the ``blastvox`` command."""

from blastvox.cli.app import main

main()
