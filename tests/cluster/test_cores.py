"""The cores of a cluster's workers (sswjax.cluster.cores): processes of one namespace claim
distinct cores, a core freed by a process that ended is claimed again, other namespaces do not
see the claims, and a process that finds every core held shares one."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

pytestmark = pytest.mark.skipif(
    not hasattr(os, "sched_getaffinity") or len(os.sched_getaffinity(0)) < 2,
    reason="CPU affinity (Linux) and two cores")

# Claims a core, prints it and the process's cores, then holds the claim until stdin closes.
_CLAIM = """
import os, sys
from sswjax.cluster.cores import claim_core
core = claim_core(sys.argv[1], folder=sys.argv[2])
print(core, sorted(os.sched_getaffinity(0)), flush=True)
sys.stdin.read()
"""


def _claimer(namespace, folder):
    process = subprocess.Popen([sys.executable, "-c", _CLAIM, namespace, str(folder)],
                               stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    core, cores = process.stdout.readline().split(" ", 1)
    assert cores.strip() == f"[{core}]"  # pinned to the core it claimed
    return process, int(core)


def _end(process):
    process.stdin.close()
    assert process.wait(timeout=60) == 0


def test_claims_are_distinct_per_namespace_and_a_freed_core_is_claimed_again(tmp_path):
    cores = sorted(os.sched_getaffinity(0))
    held = [_claimer("cluster-a", tmp_path) for _ in cores]
    assert sorted(core for _, core in held) == cores           # one core each
    other, _ = _claimer("cluster-b", tmp_path)                # another cluster: its own claims
    extra, shared = _claimer("cluster-a", tmp_path)           # every core held: it shares one
    assert shared in cores
    _end(extra)
    first, freed = held.pop(0)
    _end(first)                                                # its lock goes with the process
    again, core = _claimer("cluster-a", tmp_path)
    assert core == freed
    for process in [again, other, *(process for process, _ in held)]:
        _end(process)


def test_a_process_claims_once_per_namespace(tmp_path):
    code = ("import sys\nfrom sswjax.cluster.cores import claim_core\n"
            f"print(claim_core('a', folder={str(tmp_path)!r}) == "
            f"claim_core('a', folder={str(tmp_path)!r}))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert done.stdout.strip() == "True", done.stderr
