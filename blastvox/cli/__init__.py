"""Thin command-line layer: argument parsing, progress and messages; no physics here.

Each command lives in its own module and imports the heavy stage modules
inside the command function, so ``blastvox --help`` stays fast.
"""
