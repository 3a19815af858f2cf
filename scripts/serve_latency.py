#!/usr/bin/env python3
"""Trigger-to-reply latency of a running `camplace serve`, from this client's clock, and
the service's memory while it is triggered (Python standard library only; Linux /proc).

    python3 scripts/serve_latency.py 127.0.0.1 50010 --count 1000 --pid $(pidof camplace)

Prints p50/p90/p99/max of the latency, the replies by status, and the service's resident
memory (VmRSS) after every 100 triggers with its peak (VmHWM), to show it is not growing.
"""

import argparse
import socket
import sys
import time


def rss_kb(pid, key):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith(key + ":"):
                return int(line.split()[1])
    return None


def percentile(sorted_values, q):
    rank = max(1, min(len(sorted_values), -(-int(q * len(sorted_values)) // 100)))
    return sorted_values[rank - 1]


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("host")
    p.add_argument("port", type=int)
    p.add_argument("--count", type=int, default=1000)
    p.add_argument("--pid", type=int, help="the service's process id, for its memory")
    a = p.parse_args()
    latencies, statuses, memory = [], {}, []
    with socket.create_connection((a.host, a.port), timeout=30) as sock:
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        f = sock.makefile("rwb")
        for i in range(1, a.count + 1):
            t = time.perf_counter()
            f.write(b"TRIGGER %d\n" % i)
            f.flush()
            line = f.readline(4096)
            latencies.append((time.perf_counter() - t) * 1e3)
            status = line.split(b" ", 1)[0].decode("ascii").strip()
            statuses[status] = statuses.get(status, 0) + 1
            if a.pid and i % 100 == 0:
                memory.append((i, rss_kb(a.pid, "VmRSS")))
    s = sorted(latencies)
    print(
        f"{len(s)} triggers: p50 {percentile(s, 50):.1f} ms, p90 {percentile(s, 90):.1f} ms, "
        f"p99 {percentile(s, 99):.1f} ms, max {s[-1]:.1f} ms; replies {statuses}"
    )
    if a.pid:
        print("VmRSS after n triggers: " + ", ".join(f"{n}: {kb / 1024:.1f} MB" for n, kb in memory))
        print(f"peak RSS (VmHWM): {rss_kb(a.pid, 'VmHWM') / 1024:.1f} MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
