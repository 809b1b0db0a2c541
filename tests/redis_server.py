"""A real ``redis-server`` for the tests of the Redis state store, on a free loopback port.

It runs with the configuration docs/service.md asks for (the append-only file, fsynced at
every write; no snapshots), in a folder of its own, so that it can be killed and started
again on the same data. The tests need the Debian package ``redis-server`` (``.ci/run``
installs it when it is missing): without it they fail, they are not skipped.
"""

from __future__ import annotations

import shutil
import signal
import subprocess
import time
from pathlib import Path

import redis
from servers import free_port

__all__ = ["RedisServer"]

STARTUP_TIMEOUT_S = 20.0


class RedisServer:
    """``redis-server`` on ``127.0.0.1``, started at once.

    Parameters
    ----------
    folder
        Where it keeps its append-only file.
    """

    def __init__(self, folder: Path) -> None:
        binary = shutil.which("redis-server")
        if binary is None:
            raise RuntimeError("the Redis tests need redis-server: apt-get install redis-server (.ci/run installs it)")
        self.command = [
            binary,
            "--bind",
            "127.0.0.1",
            "--port",
            str(free_port()),
            "--dir",
            str(folder),
            "--save",
            "",
            "--appendonly",
            "yes",
            "--appendfsync",
            "always",
        ]
        self.port = int(self.command[4])
        self.process: subprocess.Popen[bytes]
        self.start()

    def url(self, database: int = 0) -> str:
        """The URL of one of its databases."""
        return f"redis://127.0.0.1:{self.port}/{database}"

    def client(self, database: int = 0) -> redis.Redis:
        """A client of one of its databases."""
        return redis.Redis(port=self.port, db=database)

    def start(self) -> None:
        """Start it (again, on the data it kept) and wait until it answers."""
        self.process = subprocess.Popen(self.command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        deadline = time.monotonic() + STARTUP_TIMEOUT_S
        with self.client() as client:
            while time.monotonic() < deadline:
                try:
                    client.ping()
                    return
                except redis.exceptions.BusyLoadingError:
                    time.sleep(0.05)
                except redis.ConnectionError:
                    if self.process.poll() is not None:
                        raise RuntimeError(f"redis-server exited with status {self.process.returncode}") from None
                    time.sleep(0.05)
        self.kill()
        raise RuntimeError(f"redis-server did not answer within {STARTUP_TIMEOUT_S} s")

    def kill(self) -> None:
        """SIGKILL: Redis gets no chance to write anything more."""
        self.process.send_signal(signal.SIGKILL)
        self.process.wait(timeout=10)

    def pause(self) -> None:
        """SIGSTOP: connections stay open, nothing is answered (a hung server)."""
        self.process.send_signal(signal.SIGSTOP)

    def resume(self) -> None:
        """SIGCONT after :meth:`pause`."""
        self.process.send_signal(signal.SIGCONT)

    def stop(self) -> None:
        """Stop it, if it runs."""
        if self.process.poll() is None:
            self.resume()
            self.process.terminate()
            self.process.wait(timeout=10)
