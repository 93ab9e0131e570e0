"""``python -m navgate``: the same as the ``navgate`` console command (and ``python -m
navgate.cli``)."""

from navgate.cli import main

main()
