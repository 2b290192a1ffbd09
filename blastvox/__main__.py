"""``python -m blastvox`` is the ``blastvox`` command."""

try:
    from blastvox.cli.entry import main
except KeyboardInterrupt:  # Ctrl-C before the entry point could set its handlers
    import sys

    print("blastvox: interrupted; no partial output left", file=sys.stderr)
    sys.exit(130)

main()
