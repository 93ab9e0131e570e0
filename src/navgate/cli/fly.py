"""``navgate fly``: placeholder replaced by the flight command (issue 2)."""

import click


@click.command()
def fly() -> None:
    """Run a GPS-denied flight (being written)."""
    raise SystemExit(0)
