"""The memory allocator both sides of a PyTorch comparison run with (scripts/compare_torch_*.py).

Why: PyTorch allocates a fresh output for every op. glibc returns blocks above 32 MiB to the OS
and maps them again on the next op, so every op of a large tensor pays a page fault per 4 KiB.
On some VMs a fault costs 10-20 us: on an AMD EPYC of family 26 (2026-11-27), `x * 2` of 16M floats took
140 ms with a fresh output and 2.6 ms into a kept one, and the elementwise chain 680-1690 ms
against 44 ms. That measures the VM, not PyTorch, so the anchor runs with jemalloc told never to
give memory back (PyTorch's CPU performance guide recommends jemalloc or tcmalloc).

`--allocator jemalloc` (the default when Debian's libjemalloc2 is installed: `scripts/install_deps.sh
--anchors`) re-executes the script with LD_PRELOAD and MALLOC_CONF set; `streetlight-bench`, a
child process, inherits both, so the two sides share one allocator. `--allocator system` keeps
glibc's (the figures before 2026-11-27).
"""
import os
import sys

JEMALLOC = "/usr/lib/x86_64-linux-gnu/libjemalloc.so.2"
NEVER_RETURN = "dirty_decay_ms:-1,muzzy_decay_ms:-1,retain:true"
_MARK = "STREETLIGHT_ANCHOR_ALLOCATOR"


def add_argument(ap):
    default = "jemalloc" if os.path.exists(JEMALLOC) else "system"
    ap.add_argument("--allocator", choices=("jemalloc", "system"), default=default,
                    help=f"allocator of both sides (default here: {default}; scripts/anchor_allocator.py)")


def use(choice):
    """Re-executes this process under `choice` unless it already runs under it; returns its name."""
    if choice == "system" or os.environ.get(_MARK) == choice:
        return choice
    if not os.path.exists(JEMALLOC):
        print(f"error: --allocator jemalloc needs {JEMALLOC} (apt-get install libjemalloc2)", file=sys.stderr)
        sys.exit(2)
    env = dict(os.environ, LD_PRELOAD=JEMALLOC, MALLOC_CONF=NEVER_RETURN, **{_MARK: choice})
    sys.stdout.flush()
    sys.stderr.flush()
    os.execve(sys.executable, [sys.executable] + sys.argv, env)
    return choice  # not reached
