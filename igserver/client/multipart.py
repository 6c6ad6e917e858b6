"""The MJPEG stream's body: multipart/x-mixed-replace parts, each with a Content-Length."""

from __future__ import annotations

from typing import Iterator


class MultipartJpegParser:
    """Incremental parser of a multipart/x-mixed-replace body: ``feed(chunk)`` -> the JPEGs completed by it."""

    def __init__(self) -> None:
        self.buffer = b""

    def feed(self, chunk: bytes) -> list[bytes]:
        self.buffer += chunk
        out = []
        while True:
            head_end = self.buffer.find(b"\r\n\r\n")
            if head_end < 0:
                break
            headers = self.buffer[:head_end].decode("latin-1").lower()
            length = next((int(line.split(":", 1)[1]) for line in headers.split("\r\n")
                           if line.startswith("content-length:")), None)
            if length is None:
                raise ValueError("multipart part without Content-Length")
            end = head_end + 4 + length
            if len(self.buffer) < end:
                break
            out.append(self.buffer[head_end + 4:end])
            self.buffer = self.buffer[end:].lstrip(b"\r\n")
        return out


def iter_multipart_jpegs(chunks: Iterator[bytes]) -> Iterator[bytes]:
    """JPEG payloads of a multipart/x-mixed-replace body (uses each part's Content-Length)."""
    parser = MultipartJpegParser()
    for chunk in chunks:
        yield from parser.feed(chunk)
