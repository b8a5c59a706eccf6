#!/usr/bin/env python3
"""A slow link on localhost: a TCP proxy that delays what the server sends
by --delay-ms and shares --mbit among all connections, as `tc netem delay
20ms rate 100mbit` on the server's side of a link would (a round trip of
the delay; requests go through at once).

    scripts/slowlink.py --listen 127.0.0.1:28333 --to 127.0.0.1:8333

Prints "listening" on stdout once it accepts connections; runs until killed.
"""

import argparse
import asyncio
import sys
import time


class Link:
    """The downstream direction's rate, shared by every connection."""

    def __init__(self, mbit):
        self.bytes_per_s = mbit * 1e6 / 8
        self.free_at = 0.0

    def departure(self, n):
        """When n bytes handed over now have left the link."""
        now = time.monotonic()
        start = max(now, self.free_at)
        self.free_at = start + n / self.bytes_per_s
        return self.free_at


async def pump(reader, writer, delay_s=0.0, link=None):
    """Copies reader to writer; with a link, each piece arrives delay_s
    after it has left the link at its rate."""
    queue = asyncio.Queue()

    async def send():
        while True:
            item = await queue.get()
            if item is None:
                break
            due, data = item
            wait = due - time.monotonic()
            if wait > 0:
                await asyncio.sleep(wait)
            writer.write(data)
            await writer.drain()
        writer.close()

    sender = asyncio.ensure_future(send())
    try:
        while True:
            data = await reader.read(64 << 10)
            if not data:
                break
            due = time.monotonic() if link is None else link.departure(len(data)) + delay_s
            await queue.put((due, data))
    except (ConnectionError, OSError):
        pass
    await queue.put(None)
    try:
        await sender
    except (ConnectionError, OSError):
        pass


async def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--listen", default="127.0.0.1:28333")
    parser.add_argument("--to", default="127.0.0.1:8333")
    parser.add_argument("--delay-ms", type=float, default=20.0)
    parser.add_argument("--mbit", type=float, default=100.0)
    args = parser.parse_args()
    link = Link(args.mbit)
    to_host, to_port = args.to.rsplit(":", 1)

    async def serve(client_reader, client_writer):
        try:
            server_reader, server_writer = await asyncio.open_connection(to_host, int(to_port))
        except OSError:
            client_writer.close()
            return
        await asyncio.gather(
            pump(client_reader, server_writer),
            pump(server_reader, client_writer, args.delay_ms / 1e3, link),
        )

    host, port = args.listen.rsplit(":", 1)
    server = await asyncio.start_server(serve, host, int(port))
    print("listening", flush=True)
    async with server:
        await server.serve_forever()


if __name__ == "__main__":
    try:
        asyncio.run(main())
    except KeyboardInterrupt:
        sys.exit(0)
