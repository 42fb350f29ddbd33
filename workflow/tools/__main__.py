"""``python -m workflow.tools NAME [options]``: run the tool NAME (``--help`` lists them)."""

import importlib
import sys

from sim.settings_file import SettingsFileError

from . import TOOLS, module, summary
from ._cli import Refusal

USAGE = "usage: python -m workflow.tools NAME [options]  (python -m workflow.tools NAME --help)"


def main(argv=None):
    """Run the tool ``argv[0]`` with the options after it; returns its exit status.

    A tool's refusal (:class:`workflow.tools._cli.Refusal`, or a settings file
    that cannot be read) is printed as one line naming the tool, with status 2.
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        print(USAGE + "\n\ntools:")
        for name in TOOLS:
            print(f"  {name:22} {summary(name)}")
        return 0 if argv else 2
    name, options = argv[0], argv[1:]
    if name not in TOOLS:
        print(f"{USAGE}\nunknown tool {name!r}; tools: {', '.join(TOOLS)}", file=sys.stderr)
        return 2
    # imported here, the one asked for: the tools load what the others never need
    tool = importlib.import_module(f"{__package__}.{module(name)}")
    sys.argv = [f"python -m workflow.tools {name}", *options]  # argparse's usage line names it so
    try:
        status = tool.main(options)
    except (Refusal, SettingsFileError) as exc:
        print(f"python -m workflow.tools {name}: {exc}", file=sys.stderr)
        return 2
    return status if isinstance(status, int) else 0


if __name__ == "__main__":
    raise SystemExit(main())
