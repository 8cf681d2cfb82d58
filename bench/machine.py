"""The machine a benchmark ran on, as one line and as a dict, so that every table says where it
was measured (timings and even ratios against a peer differ between processor generations:
spot's and the teapot's incoherent rays read 0.78-1.00x Embree on a Zen 3 VM and 1.23-1.55x on a
Zen 5 VM; BENCHMARKS.md, "Rays against Embree from the command line").

Read from Linux's /proc/cpuinfo and /sys (elsewhere the fields it cannot read are "?"), and the
versions of the packages compared.
"""

import importlib.metadata
import os
import pathlib
import platform


def _cpuinfo():
    fields = {}
    try:
        for line in pathlib.Path("/proc/cpuinfo").read_text().splitlines():
            key, _, value = line.partition(":")
            key = key.strip()
            if key and key not in fields:
                fields[key] = value.strip()
    except OSError:
        pass
    return fields


def _caches():
    """{'L1d': '32K', 'L2': '512K', ...} of CPU 0."""
    caches = {}
    for index in sorted(pathlib.Path("/sys/devices/system/cpu/cpu0/cache").glob("index*")):
        try:
            level = (index / "level").read_text().strip()
            kind = (index / "type").read_text().strip()
            size = (index / "size").read_text().strip()
        except OSError:
            continue
        if kind == "Instruction":
            continue
        caches[f"L{level}{'d' if kind == 'Data' else ''}"] = size
    return caches


def _version(package):
    try:
        return importlib.metadata.version(package)
    except importlib.metadata.PackageNotFoundError:
        return None


def machine(packages=("hbv", "numpy", "embreex", "open3d-cpu", "trimesh")):
    """What the machine and the compared packages are."""
    cpu = _cpuinfo()
    return {
        "cpu": cpu.get("model name", platform.processor() or "?"),
        "vendor": cpu.get("vendor_id", "?"),
        "family": cpu.get("cpu family", "?"),
        "model": cpu.get("model", "?"),
        "cores": os.cpu_count(),
        "caches": _caches(),
        "avx512": "avx512f" in cpu.get("flags", "").split(),
        "python": platform.python_version(),
        "packages": {p: v for p in packages if (v := _version(p))},
    }


def describe(m):
    """One line: `AMD EPYC (AuthenticAMD family 25 model 1), 2 cores, L1d 32K L2 512K ...`."""
    caches = " ".join(f"{k} {v}" for k, v in m["caches"].items())
    packages = ", ".join(f"{p} {v}" for p, v in m["packages"].items())
    return (f"{m['cpu']} ({m['vendor']} family {m['family']} model {m['model']}"
            f"{', AVX-512' if m['avx512'] else ''}), {m['cores']} cores, {caches}; "
            f"Python {m['python']}; {packages}")
