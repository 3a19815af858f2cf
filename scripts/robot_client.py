#!/usr/bin/env python3
"""An example robot client of `camplace serve` (CAMPLACE/1, docs/robot-interface.md), with
the Python standard library only: sends TRIGGER N times and prints each reply's status,
frame, score and pose, read back into numbers.

    python3 scripts/robot_client.py 127.0.0.1 50010 --count 3
"""

import argparse
import socket
import sys


def ask(sock_file, request):
    """Sends one request line and returns the reply line without its line end."""
    sock_file.write((request + "\n").encode("ascii"))
    sock_file.flush()
    line = sock_file.readline(4096)
    if not line.endswith(b"\n"):
        raise ConnectionError("the service closed the connection")
    return line.decode("ascii").rstrip("\n")


def parse_reply(line):
    """A reply's status, its reason word (REJECTED, BUSY, BAD_REQUEST) and its key=value fields."""
    words = line.split(" ")
    status, reason, fields = words[0], None, {}
    for i, word in enumerate(words[1:]):
        if "=" in word:
            key, value = word.split("=", 1)
            fields[key] = value
        elif i == 0:
            reason = word
    return status, reason, fields


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("host")
    p.add_argument("port", type=int)
    p.add_argument("--count", type=int, default=1, help="triggers to send")
    p.add_argument("--timeout", type=float, default=10.0, help="seconds to wait for a reply")
    a = p.parse_args()
    with socket.create_connection((a.host, a.port), timeout=a.timeout) as sock:
        f = sock.makefile("rwb")
        print(ask(f, "VERSION"))
        for i in range(1, a.count + 1):
            status, reason, fields = parse_reply(ask(f, f"TRIGGER {i}"))
            if status == "OK":
                pose = [float(v) for v in fields["pose"].split(",")]
                print(f"{i}: OK frame {fields['frame']} score {fields['score']} pose {pose}")
            else:
                print(f"{i}: {status} {reason or ''} {fields}")
        print(ask(f, "STATUS"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
