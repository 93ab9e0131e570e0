"""``python -m navgate.cli``: the same as the ``navgate`` console command."""

from navgate.cli import main

main()
