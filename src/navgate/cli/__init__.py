"""The ``navgate`` command line.

Each sub-command lives in its own module and is imported only when it is run, so that
``navgate --help`` stays fast and a sub-command's heavy dependencies (numba, Amaranth,
Yosys) load only when needed. To add a command, add one line to ``COMMANDS``.

Errors: a sub-command raises :class:`navgate.cli.common.CliError` (or a click usage
error) and the user sees exactly one line on stderr, ``navgate <cmd>: error: ...``,
with exit status 2 and no traceback.
"""

from __future__ import annotations

import importlib
import os
import sys

import click

from navgate import __version__
from navgate.cli.common import (
    INTERRUPTED,
    CliError,
    interrupted_by,
    os_error_message,
    sigint_flagged,
    warning_handler,
)

#: command name -> "module:attribute" of a click command
COMMANDS: dict[str, str] = {
    "fly": "navgate.cli.fly:fly",
    "campaign": "navgate.cli.campaign:campaign",
    "ahrs": "navgate.cli.ahrs:ahrs",
    "gpsins": "navgate.cli.gpsins:gpsins",
    "build": "navgate.cli.build:build",
    "report": "navgate.cli.build:report",
    "kf2x2": "navgate.cli.kf2x2:kf2x2",
    "replay": "navgate.cli.replay:replay",
    "tinykalman": "navgate.cli.tinykalman:tinykalman",
    "tiles": "navgate.cli.tiles:tiles",
    "trn-serve": "navgate.cli.trn_serve:trn_serve",
    "cache": "navgate.cli.cache:cache",
}


class LazyGroup(click.Group):
    """A click group that imports each sub-command on first use."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(COMMANDS)

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        target = COMMANDS.get(name)
        if target is None:
            return None
        module_name, attribute = target.split(":")
        return getattr(importlib.import_module(module_name), attribute)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="navgate")
def cli() -> None:
    """navgate: GPS-denied navigation, from reference model to verified gateware."""


def _one_line(message: str) -> str:
    return " ".join(str(message).split())


def main(argv: list[str] | None = None) -> None:
    """Entry point: run the group, turning every failure into one stderr line.

    Expected failures (CliError, click usage errors, any OSError) exit 2; an interrupt exits
    130; anything else is a bug, reported as one ``internal error`` line with exit 3 (set
    ``NAVGATE_DEBUG=1`` to see the traceback). Library warnings become one line each
    (:func:`navgate.cli.common.warning_handler`).
    """
    args = sys.argv[1:] if argv is None else list(argv)
    if not args:  # plain ``navgate``: the help, not a usage error squeezed into one line
        args = ["--help"]
    command = args[0] if args and not args[0].startswith("-") else None
    prefix = f"navgate {command}" if command in COMMANDS else "navgate"
    try:
        with sigint_flagged(), warning_handler(prefix):
            cli.main(args=args, prog_name="navgate", standalone_mode=False)
            if INTERRUPTED.is_set():  # an interrupt that something swallowed: still one
                raise KeyboardInterrupt
    except click.exceptions.Exit as exit_:
        sys.exit(exit_.exit_code)
    except click.exceptions.Abort:  # click's form of KeyboardInterrupt
        click.echo(f"{prefix}: interrupted (no partial results written)", err=True)
        sys.exit(130)
    except click.ClickException as error:
        click.echo(f"{prefix}: error: {_one_line(error.format_message())}", err=True)
        sys.exit(2)
    except CliError as error:
        click.echo(f"{prefix}: error: {_one_line(str(error))}", err=True)
        sys.exit(2)
    except KeyboardInterrupt:
        click.echo(f"{prefix}: interrupted (no partial results written)", err=True)
        sys.exit(130)
    except OSError as error:
        click.echo(f"{prefix}: error: {_one_line(os_error_message(error, 'cannot access'))}",
                   err=True)
        sys.exit(2)
    except MemoryError:
        click.echo(f"{prefix}: error: out of memory", err=True)
        sys.exit(2)
    except Exception as error:  # noqa: BLE001 - the last line of defence against tracebacks
        if interrupted_by(error):  # e.g. SystemError from a numba function interrupted
            click.echo(f"{prefix}: interrupted (no partial results written)", err=True)
            sys.exit(130)
        if os.environ.get("NAVGATE_DEBUG"):
            raise
        click.echo(f"{prefix}: internal error: {type(error).__name__}: "
                   f"{_one_line(str(error))[:300]} (a bug; NAVGATE_DEBUG=1 shows the traceback)",
                   err=True)
        sys.exit(3)


if __name__ == "__main__":  # pragma: no cover
    main()
