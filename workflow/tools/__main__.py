"""``python -m workflow.tools NAME [options]``: run the tool NAME (``--help`` lists them)."""

import importlib
import sys

from . import TOOLS, summary

USAGE = "usage: python -m workflow.tools NAME [options]  (python -m workflow.tools NAME --help)"


def main(argv=None):
    """Run the tool ``argv[0]`` with the options after it; returns its exit status."""
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
    tool = importlib.import_module(f"{__package__}.{name}")
    sys.argv = [f"python -m workflow.tools {name}", *options]  # argparse's usage line names it so
    status = tool.main(options)
    return status if isinstance(status, int) else 0


if __name__ == "__main__":
    raise SystemExit(main())
