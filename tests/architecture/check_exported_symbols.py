#!/usr/bin/env python3
"""No executable of the project exports a C++ symbol of its own or of a header-only library.

An executable's dynamic symbol table may hold weak template instances (Eigen's, ours) whenever
a shared library it loads uses the same instance; the loader then binds the library's calls to
the executable's copy, compiled with other flags. libgmsh's Eigen QR allocated through ours and
freed through its own inlined code that way. The project compiles with hidden visibility, so
such symbols must not appear; this check fails naming the executable and the first symbols.

Usage: check_exported_symbols.py <executable>...
"""
import subprocess
import sys

# Namespaces whose instances a shared library may also hold: ours and the header-only libraries'.
WATCHED = ("touchstone::", "Eigen::", "toml::", "nlohmann::", "CLI::")


def exported_watched_symbols(executable):
    listing = subprocess.run(["nm", "-D", "--defined-only", "-C", executable], check=True,
                             capture_output=True, text=True).stdout
    return [line.split(" ", 2)[-1] for line in listing.splitlines()
            if any(name in line for name in WATCHED)]


def main(executables):
    if not executables:
        print(__doc__, file=sys.stderr)
        return 2
    failed = False
    for executable in executables:
        symbols = exported_watched_symbols(executable)
        if symbols:
            failed = True
            print(f"{executable}: exports {len(symbols)} symbol(s) a shared library could bind to, e.g.:")
            for symbol in symbols[:5]:
                print(f"  {symbol}")
        else:
            print(f"{executable}: exports none of {', '.join(WATCHED)}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
