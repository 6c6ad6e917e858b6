"""Python host client for igserver protocol v1 (sync and asyncio); the ``igclient`` CLI is ``igserver.client.cli``.

    from igserver.client import IGClient
"""

from .core import (
    AsyncFrameStream,
    AsyncIGClient,
    Frame,
    FrameStream,
    IGClient,
    IGError,
    iter_multipart_jpegs,
)

__all__ = ["AsyncFrameStream", "AsyncIGClient", "Frame", "FrameStream", "IGClient", "IGError", "iter_multipart_jpegs"]
