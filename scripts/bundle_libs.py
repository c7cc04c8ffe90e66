#!/usr/bin/env python3
"""Makes the add-on's engine library self-contained: copies every shared library it needs beyond
the base system (glibc, libstdc++, libgcc_s, zlib) next to it and gives it and them the RUNPATH
$ORIGIN, so that the add-on loads wherever it is installed, without Debian's Embree, TBB, OpenEXR
or OpenSubdiv packages.

    scripts/bundle_libs.py DIR/libphotonlm.so      (the copy in the add-on's staging folder)

    scripts/bundle_libs.py --program EXE DIR LIBDIR
                           (a copy of EXE in DIR that finds its libraries in LIBDIR, a bundled folder)

Also used by the tests: `scripts/bundle_libs.py --check DIR/libphotonlm.so` lists how each
dependency resolves (ldd, with LD_LIBRARY_PATH unset) and exits 1 if one is missing or resolves
outside DIR and the base system.
"""
import os
import re
import shutil
import subprocess
import sys

# Shared libraries every Linux system that runs Blender has (sonames without the version).
BASE = ("linux-vdso", "ld-linux", "libc", "libm", "libpthread", "libdl", "librt", "libstdc++", "libgcc_s", "libz")


def is_base(soname):
    stem = soname.split(".so")[0]
    return stem in BASE or stem.startswith("ld-linux")


def resolved(path):
    """(soname, resolved path or None) of every library ldd lists for path, environment cleared."""
    env = {k: v for k, v in os.environ.items() if k not in ("LD_LIBRARY_PATH", "LD_PRELOAD")}
    out = subprocess.run(["ldd", path], check=True, capture_output=True, text=True, env=env).stdout
    deps = []
    for line in out.splitlines():
        m = re.match(r"\s*(\S+)\s+=>\s+(not found|\S+)", line)
        if m:
            deps.append((m.group(1), None if m.group(2) == "not found" else m.group(2)))
        else:
            m = re.match(r"\s*(\S+)\s+\(0x", line)
            if m:
                deps.append((os.path.basename(m.group(1)), m.group(1)))
    return deps


def bundle(library):
    folder = os.path.dirname(os.path.abspath(library))
    copied = []
    for soname, path in resolved(library):
        if is_base(soname):
            continue
        if path is None:
            sys.exit("bundle_libs: %s needs %s, which is not installed" % (library, soname))
        target = os.path.join(folder, soname)
        if not os.path.exists(target):
            shutil.copy2(os.path.realpath(path), target)
            os.chmod(target, 0o755)
            copied.append(soname)
    for name in [os.path.basename(library)] + copied:
        subprocess.run(["patchelf", "--set-rpath", "$ORIGIN", os.path.join(folder, name)], check=True)
    size = sum(os.path.getsize(os.path.join(folder, n)) for n in copied)
    print("bundle_libs: %d libraries (%.1f MB) beside %s: %s"
          % (len(copied), size / 1e6, os.path.basename(library), " ".join(sorted(copied))))


def program(exe, folder, libdir):
    os.makedirs(folder, exist_ok=True)
    target = os.path.join(folder, os.path.basename(exe))
    shutil.copy2(exe, target)
    rpath = os.path.join("$ORIGIN", os.path.relpath(os.path.abspath(libdir), os.path.abspath(folder)))
    subprocess.run(["patchelf", "--set-rpath", rpath, target], check=True)


def check(library):
    folder = os.path.dirname(os.path.realpath(library))
    bad = []
    for soname, path in resolved(library):
        if path is None:
            bad.append("%s: not found" % soname)
        elif not is_base(soname) and os.path.dirname(os.path.realpath(path)) != folder:
            bad.append("%s: %s (outside the add-on)" % (soname, path))
        print("bundle_libs: %-28s %s" % (soname, path))
    for b in bad:
        print("bundle_libs: ERROR %s" % b)
    return 1 if bad else 0


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--check":
        sys.exit(check(sys.argv[2]))
    if len(sys.argv) == 5 and sys.argv[1] == "--program":
        sys.exit(program(*sys.argv[2:]))
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    bundle(sys.argv[1])
