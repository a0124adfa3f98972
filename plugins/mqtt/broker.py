"""An embedded MQTT broker (amqtt) for the demo, so it works with nothing else installed.

The broker runs in a background thread with its own asyncio event loop, on a free port of
the loopback interface only (nothing outside the machine can reach it). amqtt is the ``demo``
extra: ``pip install 'hapticdesk[demo]'``; it is imported only here.
"""

from __future__ import annotations

import asyncio
import logging
import socket
import threading
from types import TracebackType
from typing import Any

from hapticdesk.errors import ConfigError

log = logging.getLogger(__name__)


def free_loopback_port() -> int:
    """A TCP port on 127.0.0.1 nobody listens on (the OS picks it)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class EmbeddedBroker:
    """``with EmbeddedBroker() as broker: …`` gives ``broker.url`` (mqtt://127.0.0.1:PORT)."""

    def __init__(self, port: int | None = None) -> None:
        self.port = port or free_loopback_port()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._broker: Any = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None

    @property
    def url(self) -> str:
        return f"mqtt://127.0.0.1:{self.port}"

    def start(self, timeout: float = 10.0) -> EmbeddedBroker:
        """Start the broker and wait until it accepts connections."""
        try:
            from amqtt.broker import Broker
        except ImportError:
            raise ConfigError(
                None,
                "the embedded MQTT broker needs amqtt: pip install 'hapticdesk[demo]' "
                "(or give a broker with --mqtt mqtt://HOST:PORT)",
            ) from None
        # amqtt reports every connection at INFO and more; the demo has its own output
        logging.getLogger("amqtt").setLevel(logging.ERROR)
        config = {
            "listeners": {"default": {"type": "tcp", "bind": f"127.0.0.1:{self.port}"}},
            "plugins": {
                "amqtt.plugins.authentication.AnonymousAuthPlugin": {"allow_anonymous": True}
            },
        }

        def serve() -> None:
            loop = asyncio.new_event_loop()
            self._loop = loop
            asyncio.set_event_loop(loop)
            try:

                async def begin() -> None:
                    self._broker = Broker(config)
                    await self._broker.start()

                loop.run_until_complete(begin())
            except BaseException as err:  # a busy port, a bad amqtt install
                self._error = err
                self._ready.set()
                loop.close()
                return
            self._ready.set()
            loop.run_forever()
            loop.close()

        self._thread = threading.Thread(target=serve, name="embedded MQTT broker", daemon=True)
        self._thread.start()
        if not self._ready.wait(timeout) or self._error is not None:
            raise ConfigError(
                None, f"the embedded MQTT broker did not start on port {self.port}: {self._error}"
            )
        log.info("embedded MQTT broker on %s", self.url)
        return self

    def stop(self, timeout: float = 5.0) -> None:
        """Shut the broker down (idempotent)."""
        loop, broker = self._loop, self._broker
        if loop is None or broker is None or not loop.is_running():
            return
        future = asyncio.run_coroutine_threadsafe(broker.shutdown(), loop)
        try:
            future.result(timeout)
        except Exception as err:  # shutting down: report, do not fail the demo
            log.warning("embedded MQTT broker: shutdown: %s", err)
        loop.call_soon_threadsafe(loop.stop)
        if self._thread is not None:
            self._thread.join(timeout)
        self._broker = None

    def __enter__(self) -> EmbeddedBroker:
        return self.start()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()
