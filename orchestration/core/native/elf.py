"""What a Linux shared library needs from its C library: the glibc symbol versions in its ELF version needs.

A library linked against glibc records, per needed library, the versions of the symbols it uses
(``SHT_GNU_verneed``: ``hypot@GLIBC_2.35``, ``exp@GLIBC_2.29``, ...); the dynamic loader refuses the
library on a glibc older than the newest of them. ``objdump -T`` shows the same; this reads the ELF itself
(64-bit, little-endian: x86_64 and aarch64), so the check needs no binutils.
"""

from __future__ import annotations

import struct

__all__ = ["ELFError", "glibc_versions", "machine"]

SHT_GNU_VERNEED = 0x6FFFFFFE
MACHINES = {62: "x86_64", 183: "aarch64", 3: "x86", 40: "arm"}


class ELFError(ValueError):
    """Not a 64-bit little-endian ELF file, or one cut short."""


def _header(data: bytes) -> tuple:
    if data[:4] != b"\x7fELF" or len(data) < 64:
        raise ELFError("not an ELF file")
    if data[4] != 2 or data[5] != 1:
        raise ELFError("not a 64-bit little-endian ELF file")
    return struct.unpack_from("<HHIQQQIHHHHHH", data, 16)


def machine(data: bytes) -> str:
    """The ELF file's machine ("x86_64", "aarch64", ...; else "machine N")."""
    number = _header(data)[1]
    return MACHINES.get(number, f"machine {number}")


def glibc_versions(data: bytes) -> list[tuple[int, ...]]:
    """The GLIBC_x.y[.z] versions the ELF file ``data`` needs, as sorted tuples of ints ((2, 2, 5), (2, 14), ...);
    empty for a file without version needs."""
    _, _, _, _, _, shoff, _, _, _, _, shentsize, shnum, _ = _header(data)
    sections = [struct.unpack_from("<IIQQQQIIQQ", data, shoff + k * shentsize) for k in range(shnum)]
    found = set()
    for _, kind, _, _, offset, _, link, count, _, _ in sections:
        if kind != SHT_GNU_VERNEED:
            continue
        strings = sections[link][4]
        at = offset
        for _ in range(count):
            _, n_aux, _, aux, following = struct.unpack_from("<HHIII", data, at)
            entry = at + aux
            for _ in range(n_aux):
                _, _, _, name, after = struct.unpack_from("<IHHII", data, entry)
                end = data.index(b"\0", strings + name)
                text = data[strings + name : end].decode("ascii", "replace")
                if text.startswith("GLIBC_") and text[6:7].isdigit():
                    found.add(tuple(int(p) for p in text[6:].split(".")))
                entry += after
            at += following
    return sorted(found)
