"""What `nvr bench` records about the machine: peak memory per renderer, the CPU, and what else ran.

Peak memory: tracemalloc misses the memory torch, Mitsuba and OIDN allocate natively, so the
process's resident set is used. On Linux the kernel's high-water mark (VmHWM) is reset by
writing 5 to /proc/self/clear_refs before each measurement, which gives each renderer its own
peak; elsewhere the growth of getrusage's ru_maxrss is used, which only shows a renderer's
peak when it exceeds every earlier one. `PeakMemory.method` says which one ran. Before each
measurement glibc's malloc_trim returns freed heap pages to the system, so memory an earlier
renderer freed but the allocator kept does not hide the next one's growth.
Other load: CPU seconds of every other process between two snapshots of /proc (Linux only).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import gc
import os
import platform
import resource
import sys
from dataclasses import dataclass
from pathlib import Path

PROC = Path("/proc")


class PeakMemory:
    """Peak resident memory above the level at `start()`, in MB."""

    def __init__(self) -> None:
        self.method = "VmHWM after /proc/self/clear_refs" if _can_reset_peak() else "ru_maxrss growth"
        self._base_kb = 0

    def start(self) -> None:
        _release_freed_memory()
        if self.method.startswith("VmHWM"):
            (PROC / "self" / "clear_refs").write_text("5")
            self._base_kb = _status_kb("VmRSS")
        else:
            self._base_kb = _maxrss_kb()

    def peak_mb(self) -> float:
        peak = _status_kb("VmHWM") if self.method.startswith("VmHWM") else _maxrss_kb()
        return max(0.0, (peak - self._base_kb) / 1024.0)


def _release_freed_memory() -> None:
    """Collect garbage and hand freed heap pages back to the system (glibc only; elsewhere nothing happens)."""
    gc.collect()
    name = ctypes.util.find_library("c")
    try:
        ctypes.CDLL(name).malloc_trim(0)
    except (OSError, AttributeError, TypeError):
        pass


def _can_reset_peak() -> bool:
    try:
        (PROC / "self" / "clear_refs").write_text("5")
        return _status_kb("VmHWM") > 0
    except OSError:
        return False


def _status_kb(field: str) -> int:
    for line in (PROC / "self" / "status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1])
    return 0


def _maxrss_kb() -> int:
    usage = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return usage // 1024 if sys.platform == "darwin" else usage  # bytes on macOS, kB on Linux


@dataclass(frozen=True)
class ProcessLoad:
    pid: int
    command: str
    cpu_seconds: float


def cpu_snapshot() -> dict[int, tuple[str, float]]:
    """CPU seconds used so far by every process (pid -> (command, seconds)); empty where /proc is missing."""
    ticks = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100
    out = {}
    for entry in PROC.glob("[0-9]*") if PROC.is_dir() else ():
        try:
            stat = (entry / "stat").read_text()
            command = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace").strip()
        except OSError:
            continue
        fields = stat[stat.rfind(")") + 2:].split()  # after "pid (name) "; utime and stime are fields 14 and 15
        out[int(entry.name)] = (command or stat[stat.find("(") + 1: stat.rfind(")")], (int(fields[11]) + int(fields[12])) / ticks)
    return out


def other_load(before: dict[int, tuple[str, float]], after: dict[int, tuple[str, float]], top: int = 5) -> list[ProcessLoad]:
    """The processes other than this one that used the most CPU between two snapshots."""
    used = []
    for pid, (command, seconds) in after.items():
        if pid == os.getpid():
            continue
        spent = seconds - before.get(pid, (command, 0.0))[1]
        if spent > 0.5:
            used.append(ProcessLoad(pid, command[:110], spent))
    return sorted(used, key=lambda p: -p.cpu_seconds)[:top]


def machine_description() -> dict[str, str]:
    """CPU model, cores and software versions, for the report."""
    import torch

    cpu = platform.processor() or platform.machine()
    cpuinfo = PROC / "cpuinfo"
    if cpuinfo.is_file():
        names = [line.split(":", 1)[1].strip() for line in cpuinfo.read_text().splitlines() if line.startswith("model name")]
        cpu = names[0] if names else cpu
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    from models.engine.onednn import cpu_has_native_bfloat16, onednn_isa_cap

    bf16 = cpu_has_native_bfloat16()
    cap = onednn_isa_cap()
    return {
        "cpu": f"{cpu}, {cores} cores usable, {'native bfloat16 (AVX512-BF16)' if bf16 else 'no native bfloat16'}"
               + (f", oneDNN capped at {cap} (ONEDNN_MAX_CPU_ISA)" if cap else "")
               + f", torch kernels {torch.backends.cpu.get_cpu_capability()}",
        "os": f"{platform.system()} {platform.release()}",
        "python": platform.python_version(),
        "torch": f"{torch.__version__}, {torch.get_num_threads()} threads, OMP_WAIT_POLICY={os.environ.get('OMP_WAIT_POLICY', 'unset')}, "
                 f"GOMP_SPINCOUNT={os.environ.get('GOMP_SPINCOUNT', 'unset')}",
        "gpu": torch.cuda.get_device_name(0) if torch.cuda.is_available() else "none",
    }
