#!/usr/bin/env python3
"""Splits a CUDA shared library's fat binary so that it can travel in pieces.

ONNX Runtime's PyPI CUDA provider (libonnxruntime_providers_cuda.so, 284 MB)
carries machine code for sm_75 ... sm_120; 77 MB of it is sm_90's (H100,
H200). `split` zeroes every other architecture's payloads in place (the
entries' headers stay, so the library's layout and its sm_90 code are
untouched) and writes those payloads, in order, to REST; the zeroed library
compresses to about 52 MB. `restore` puts them back, byte for byte.

    fatbin_split.py split SRC KEEP_SM ZEROED REST
    fatbin_split.py restore ZEROED KEEP_SM REST OUT

Only for carrying `make gpu-check` to a GPU machine without a network
(tools/gpu_check_offline/README.md); nothing in the product uses it.
"""
import struct
import sys

FATBIN_MAGIC = 0xBA55ED50
ELF_KIND = 2


def fatbin_section(data):
    """(offset, size) of the ELF64 section named .nv_fatbin."""
    if data[:4] != b"\x7fELF" or data[4] != 2:
        sys.exit("not an ELF64 file")
    shoff, = struct.unpack_from("<Q", data, 0x28)
    shentsize, shnum, shstrndx = struct.unpack_from("<HHH", data, 0x3A)
    def header(i):
        name, _, _, _, off, size = struct.unpack_from("<IIQQQQ", data, shoff + i * shentsize)
        return name, off, size
    _, stroff, _ = header(shstrndx)
    for i in range(shnum):
        name, off, size = header(i)
        end = data.index(b"\0", stroff + name)
        if data[stroff + name:end] == b".nv_fatbin":
            return off, size
    sys.exit("no .nv_fatbin section")


def payloads(data):
    """(start, length, kind, sm) of every fat-binary entry's payload."""
    off, size = fatbin_section(data)
    pos, end = off, off + size
    while pos < end:
        magic, _, header_size, fat_size = struct.unpack_from("<IHHQ", data, pos)
        if magic != FATBIN_MAGIC:
            pos += 8 if data[pos:pos + 8] == bytes(8) else 1  # alignment padding
            continue
        entry, container_end = pos + header_size, pos + header_size + fat_size
        while entry < container_end:
            kind, _, entry_header, padded, _, _, _, _, sm = struct.unpack_from("<HHIIIIIII", data, entry)
            yield entry + entry_header, padded, kind, sm
            entry += entry_header + padded
        pos = container_end


def other_architectures(data, keep):
    """(start, length) of every payload that is not sm_KEEP machine code."""
    return [(start, n) for start, n, kind, sm in payloads(data) if not (kind == ELF_KIND and sm == keep)]


def main(argv):
    if len(argv) == 5 and argv[0] == "split":
        src, keep, zeroed, rest = argv[1], int(argv[2]), argv[3], argv[4]
        data = bytearray(open(src, "rb").read())
        with open(rest, "wb") as out:
            for start, n in other_architectures(data, keep):
                out.write(data[start:start + n])
                data[start:start + n] = bytes(n)
        open(zeroed, "wb").write(data)
    elif len(argv) == 5 and argv[0] == "restore":
        zeroed, keep, rest, out = argv[1], int(argv[2]), argv[3], argv[4]
        data = bytearray(open(zeroed, "rb").read())
        with open(rest, "rb") as source:
            for start, n in other_architectures(data, keep):
                data[start:start + n] = source.read(n)
        open(out, "wb").write(data)
    else:
        sys.exit(__doc__)


if __name__ == "__main__":
    main(sys.argv[1:])
