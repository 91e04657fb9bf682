#!/usr/bin/env python3
"""Runs a command in a network namespace of its own with only loopback, up.

The node test starts roscore, rosout and sparseloop_node; roscpp's XML-RPC server binds every
interface and has no option to change that. In a namespace whose only interface is loopback,
every process of the test listens on loopback only, and the test cannot reach, or be reached
from, anything outside. Needs root or unprivileged user namespaces; without either the command
runs as it is and says so on stderr.

Usage: isolated.py COMMAND [ARG...]
"""
import ctypes
import fcntl
import os
import socket
import struct
import sys

CLONE_NEWNET = 0x40000000
CLONE_NEWUSER = 0x10000000
SIOCGIFFLAGS, SIOCSIFFLAGS, IFF_UP = 0x8913, 0x8914, 0x1


def unshare(flags):
    libc = ctypes.CDLL(None, use_errno=True)
    return libc.unshare(flags) == 0


def write(path, text):
    with open(path, "w") as f:
        f.write(text)


def loopback_up():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        request = struct.pack("16sH14s", b"lo", 0, bytes(14))
        flags = struct.unpack("16sH14s", fcntl.ioctl(s, SIOCGIFFLAGS, request))[1]
        fcntl.ioctl(s, SIOCSIFFLAGS, struct.pack("16sH14s", b"lo", flags | IFF_UP, bytes(14)))


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    uid, gid = os.getuid(), os.getgid()
    isolated = unshare(CLONE_NEWNET)
    if not isolated and unshare(CLONE_NEWUSER | CLONE_NEWNET):
        # Root inside the new user namespace (mapped to the caller): allowed to set lo up.
        write("/proc/self/setgroups", "deny")
        write("/proc/self/uid_map", f"0 {uid} 1")
        write("/proc/self/gid_map", f"0 {gid} 1")
        isolated = True
    if isolated:
        loopback_up()
        os.environ["SPARSELOOP_NET_ISOLATED"] = "1"
    else:
        print(f"isolated.py: no network namespace ({os.strerror(ctypes.get_errno())}); running "
              "without isolation: roscpp's XML-RPC servers listen on every interface",
              file=sys.stderr)
    os.execvp(sys.argv[1], sys.argv[1:])


if __name__ == "__main__":
    main()
