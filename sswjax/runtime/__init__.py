"""How a call runs, never inside the jitted pytree: execution plans and what chooses them.

=================  ==============================================================================
``plan``           ``ExecutionPlan``: tiles or strips, buckets, disparity blocks (and their checks)
``execute``        a graph run under a plan: bucketed, aligned once first, then whole, in windows,
                   or by an engine
``buckets``        shape buckets: sizes rounded up so that pairs share a compiled graph
``tiles``          a pair matched in overlapping tiles (row strips: one column of them), stitched
``carried``        row strips that hand the semi-global paths on, for the whole image's maps
``memory``         the memory model: an estimate per call, and the plan that fits (or a refusal)
``devices``        the 1-D device mesh a batch is split over
``compilation``    XLA's persistent compilation cache
``executables``    the bound on the compiled graphs a process keeps alive
``stored``         each graph's trace and executable on disk, for the next process
``graph_keys``     what a stored graph is keyed by: source, versions, arguments, host
``folder_bound``   the stored graphs' folder bounded, the least recently used files removed
=================  ==============================================================================
"""
