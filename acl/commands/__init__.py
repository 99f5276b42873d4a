"""The subcommands, one module each with ``add_parser`` and ``run``, registered in acl/cli.py COMMANDS.

What acl/cli.py itself needs of the commands' shared helpers (acl/commands/_common.py) is named here."""
from acl.commands._common import add_verbosity, exit_code, report

__all__ = ["add_verbosity", "exit_code", "report"]
