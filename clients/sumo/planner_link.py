"""The link to the planner: a Zenoh session (the wire code of clients/python/hmdp_client.py)
and, with --spawn-planner, a `planner serve` process of our own on a free loopback port.
"""

import ctypes
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(REPO, "clients", "python"))

import hmdp_client  # noqa: E402  (the project's Python client: session, query, version check)

NoAnswer = hmdp_client.NoAnswer
# Refusals before anything is sent: no key for a planner beyond this host, a bad key file.
BadInput = hmdp_client.BadInput


def free_port():
    """A free TCP port on the loopback interface (the OS picks it; free when returned)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def find_planner(explicit=None):
    """The planner binary: --planner-bin, $HMDP_PLANNER, the cargo target dirs, or PATH."""
    if explicit:
        return explicit
    if os.environ.get("HMDP_PLANNER"):
        return os.environ["HMDP_PLANNER"]
    targets = [os.environ.get("CARGO_TARGET_DIR"), os.path.join(REPO, "target")]
    for target in filter(None, targets):
        for profile in ("release", "debug"):
            path = os.path.join(target, profile, "planner")
            if os.access(path, os.X_OK):
                return path
    found = shutil.which("planner")
    if found:
        return found
    raise FileNotFoundError("no planner binary: build it (cargo build -p planner) or pass --planner-bin")


def _die_with_parent():
    # Linux: the planner gets SIGTERM when the bridge dies, however it dies.
    try:
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except OSError:
        pass


class SpawnedPlanner:
    """`planner serve --zenoh-listen tcp/127.0.0.1:<free port>`, as sim_client's --spawn-planner."""

    def __init__(self, binary, log_path, config=None, workers=None):
        self.endpoint = f"tcp/127.0.0.1:{free_port()}"
        command = [binary, "serve", "--zenoh-listen", self.endpoint]
        if workers:
            command += ["--workers", str(workers)]
        if config:
            command += ["--config", config]
        self.log_path = log_path
        self._log = open(log_path, "wb")
        env = dict(os.environ, RUST_LOG=os.environ.get("RUST_LOG", "info,zenoh=warn"))
        self.process = subprocess.Popen(
            command, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=self._log, env=env, preexec_fn=_die_with_parent
        )

    def stop(self):
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self._log.close()

    def log(self):
        with open(self.log_path, errors="replace") as f:
            return f.read()


def load_verifier(path):
    """The planner's public key file (`planner keygen`'s .pub) as a verifier; BadInput if it
    cannot be read (or the cryptography package is missing)."""
    try:
        return hmdp_client.hmdp_signing.Verifier.from_file(path)
    except (OSError, ValueError, ImportError) as e:
        raise BadInput(f"planner key {path}: {e}") from e


class PlannerLink:
    """One Zenoh client session to the planner; `decide` sends a PlanRequest, times the answer.

    With `verifier` (a hmdp_signing.Verifier of the planner's public key) an answer that does
    not verify is refused and the real one awaited, as in the Python client; `refused` counts
    them. Without one, a planner beyond this host is refused (BadInput) unless `insecure`.
    """

    def __init__(self, endpoint, timeout_s=2.0, verifier=None, insecure=False):
        hmdp_client.check_security(endpoint, verifier, insecure)
        self.endpoint = endpoint
        self.timeout_s = timeout_s
        self.verifier = verifier
        self.refused = []
        self.session = None

    def wait_ready(self, limit_s=60.0, alive=lambda: True):
        """Opens the session, then waits until the planner answers the readiness probe (the
        empty query, docs/protocol.md): a freshly started planner listens only after a while.
        """
        give_up = time.monotonic() + limit_s
        while self.session is None:
            try:
                self.session = hmdp_client.open_session(self.endpoint)
            except NoAnswer:
                if not alive():
                    raise NoAnswer("the planner exited before serving")
                if time.monotonic() > give_up:
                    raise
                time.sleep(0.2)
        while True:
            for reply in self.session.get(hmdp_client.PLAN_KEY, timeout=1.0):
                if reply.ok is not None:
                    return
            if not alive():
                raise NoAnswer("the planner exited before serving")
            if time.monotonic() > give_up:
                raise NoAnswer(f"no planner answered at {self.endpoint} within {limit_s} s")
            time.sleep(0.2)

    def decide(self, request):
        """(response dict, round trip in seconds)."""
        start = time.perf_counter()
        response = hmdp_client.ask(self.session, request, self.timeout_s, self.verifier, self.refused)
        return response, time.perf_counter() - start

    def close(self):
        if self.session is not None:
            self.session.close()


def describe(response):
    return json.dumps(response["outcome"], separators=(",", ":"))
