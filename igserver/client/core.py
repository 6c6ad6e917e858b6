"""The client's former single module: its names, for imports and installed ``igclient`` scripts that use
this path (``igserver.client.core:main``). The code lives in the modules of ``igserver.client``."""

import sys

from .cli import build_parser, main, read_scenario
from .http import AsyncIGClient, IGClient
from .latency import format_summary, latency_bench, percentile, summarize
from .multipart import MultipartJpegParser, iter_multipart_jpegs
from .stream import AsyncFrameStream, FrameStream
from .wire import DEFAULT_URL, MSGPACK, Frame, IGError

__all__ = ["AsyncFrameStream", "AsyncIGClient", "DEFAULT_URL", "Frame", "FrameStream", "IGClient", "IGError",
           "MSGPACK", "MultipartJpegParser", "build_parser", "format_summary", "iter_multipart_jpegs",
           "latency_bench", "main", "percentile", "read_scenario", "summarize"]

if __name__ == "__main__":
    sys.exit(main())
