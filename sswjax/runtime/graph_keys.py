"""The keys of the stored graphs (:mod:`sswjax.runtime.stored`): what a trace depends on (the
source, the versions, the function, its arguments' structure and shapes) and what an executable
compiled here depends on beyond it (the backend, the devices, ``XLA_FLAGS``, the CPU).
"""

from __future__ import annotations

import functools
import hashlib
import os
import platform
from collections.abc import Callable, Sequence
from pathlib import Path

import jax
import jaxlib

__all__ = ["GRAPH_SUFFIX", "graph_key", "host_digest", "source_digest"]

GRAPH_SUFFIX = ".jaxexport"
"""The suffix of a stored trace's file (:func:`graph_key`)."""


@functools.cache
def source_digest() -> str:
    """SHA-256 of the sswjax package's modules (relative path and bytes, in path order) and of
    the versions of jax and jaxlib: what a stored graph was traced from."""
    package = Path(__file__).resolve().parents[1]
    digest = hashlib.sha256(f"jax {jax.__version__} jaxlib {jaxlib.__version__}".encode())
    for path in sorted(package.rglob("*.py")):
        digest.update(str(path.relative_to(package)).encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


def _cpu_description() -> str:
    """The CPU's model and instruction-set lines of ``/proc/cpuinfo`` (each distinct line
    once), or :mod:`platform`'s names where that file is missing."""
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return f"{platform.machine()} {platform.processor()}"
    wanted = ("model name", "flags", "Features", "CPU implementer", "CPU part")
    return "\n".join(dict.fromkeys(line for line in text.splitlines() if line.startswith(wanted)))


@functools.cache
def host_digest() -> str:
    """SHA-256 of what an executable compiled in this process depends on beyond its program:
    the default backend's platform and version, its first device's kind, the device count,
    ``XLA_FLAGS`` and the CPU (:func:`_cpu_description`)."""
    device = jax.devices()[0]
    text = "\n".join([device.client.platform, device.client.platform_version,
                      device.device_kind, str(jax.device_count()),
                      os.environ.get("XLA_FLAGS", ""), _cpu_description()])
    return hashlib.sha256(text.encode()).hexdigest()


def graph_key(fn: Callable, treedef, specs: Sequence[jax.ShapeDtypeStruct],
              static: dict) -> str:
    """The file name of a stored graph: a digest of :func:`source_digest`, the backend, ``fn``'s
    module and qualified name, the traced arguments' pytree structure ``treedef`` (its repr
    holds the static options of every configuration), their ``specs`` and the ``static``
    arguments' values."""
    text = "\n".join([
        source_digest(), jax.default_backend(), str(jax.config.jax_enable_x64),
        f"{fn.__module__}.{fn.__qualname__}", repr(treedef),
        ";".join(f"{spec.shape}{spec.dtype}{spec.weak_type}" for spec in specs),
        repr(sorted(static.items())),
    ])
    return f"{fn.__name__}-{hashlib.sha256(text.encode()).hexdigest()[:40]}{GRAPH_SUFFIX}"
