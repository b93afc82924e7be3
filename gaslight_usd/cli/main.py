"""Entry point of ``gaslight2usd``."""

from __future__ import annotations

import argparse
import errno
import importlib
import logging
import sys
import traceback

from ..errors import (
    EXIT_BAD_INPUT,
    EXIT_FAILED,
    EXIT_INTERRUPTED,
    EXIT_USAGE,
    GaslightError,
)
from ..provenance import tool_version
from ..stop_signals import stop_on_signals
from ._points import attach_point_values

# OS errors that mean "this path cannot be used as given" (exit 3, bad input).
PATH_ERRNOS = {errno.EACCES, errno.EPERM, errno.EROFS, errno.ENOENT, errno.ENOTDIR,
               errno.EISDIR, errno.EEXIST, errno.ENAMETOOLONG}

# Subcommand -> module in this package; absent modules are "not built yet".
SUBCOMMANDS = ["run", "hdr", "poses", "fit", "export", "hdri", "batch", "bench", "info"]

EPILOG = """\
exit status:
  0    success
  1    the work failed (a stage could not finish)
  2    usage error, or a subcommand/method not built yet
  3    bad input: a missing or unreadable file, an empty folder, NaN pixels,
       an unknown colour space (the message names the file and the problem)
  130  interrupted; finished outputs stay, nothing is left half-written

Every subcommand takes --json (machine-readable result on stdout), -v and -q.
Run 'gaslight2usd COMMAND --help' for each command's options and examples.
"""


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The whole parser, or (``only``) the parser with that one subcommand registered.

    Each subcommand module imports what its command needs (USD, OCIO, torch...),
    so a run of one command registers just that one: ``export`` starts in a
    fraction of the time the full parser takes. ``--help`` and unknown commands
    get the full parser.
    """
    parser = argparse.ArgumentParser(
        prog="gaslight2usd",
        description="Turn a handful of LDR photos of a set into its lighting: HDR "
                    "Gaussian splats (GaSLight) as OpenUSD, EXR HDRIs and 3DGS PLY, "
                    "colour-managed with OpenColorIO.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {tool_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in SUBCOMMANDS if only is None else [only]:
        importlib.import_module(f"{__package__}._{name}").register(sub)
    return parser


STOPPABLE = ("run", "hdr", "poses", "fit", "export", "hdri", "bench")
"""Long commands: SIGTERM stops them as Ctrl-C does (:mod:`gaslight_usd.stop_signals`)."""
USES_PYCOLMAP = ("run", "poses", "fit", "bench")


def main(argv: list[str] | None = None) -> int:
    argv = attach_point_values(sys.argv[1:] if argv is None else list(argv))
    parser = build_parser(argv[0] if argv and argv[0] in SUBCOMMANDS else None)
    args = parser.parse_args(argv)
    if not getattr(args, "handler", None):
        parser.print_help()
        return EXIT_USAGE
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    try:
        if args.command in STOPPABLE:
            with stop_on_signals(preload_pycolmap=args.command in USES_PYCOLMAP):
                return int(args.handler(args) or 0)
        return int(args.handler(args) or 0)
    except GaslightError as exc:
        print(f"gaslight2usd: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("gaslight2usd: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except OSError as exc:
        if exc.filename is None:
            return _internal_error(args, exc)
        # A path the work could not write or read: the user's to fix, not a bug.
        print(f"gaslight2usd: error: {exc.filename}: {exc.strerror or exc}", file=sys.stderr)
        return EXIT_BAD_INPUT if exc.errno in PATH_ERRNOS else EXIT_FAILED
    except Exception as exc:
        return _internal_error(args, exc)


def _internal_error(args: argparse.Namespace, exc: BaseException) -> int:
    """An internal error: one line unless -v."""
    if getattr(args, "verbose", False):
        traceback.print_exc()
    print(f"gaslight2usd: internal error: {type(exc).__name__}: {exc} "
          "(run with -v for the traceback)", file=sys.stderr)
    return EXIT_FAILED


if __name__ == "__main__":
    sys.exit(main())
