"""``python -m igserver.protocol``: ``igserver serve`` on the built-in default scene (the benchmark and the
soak test start the server so). The command line sits above the protocol package: only this entry
point, which nothing imports, reaches up to it."""

import sys

from ..cli import main


def serve(argv: list[str]) -> int:
    if "--scene" not in argv:
        argv = ["--scene", "", *argv]
    return main(["serve", *argv])


if __name__ == "__main__":
    sys.exit(serve(sys.argv[1:]))
