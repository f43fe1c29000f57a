"""The ``sswjax`` command line (the console script ``sswjax = "sswjax.cli:console"``).

=================  ==============================================================================
``app``            the parser of every sub-command, ``main(argv)`` and its exit codes
``common``         the one-line-error parser, exit codes, Ctrl-C, output files
``options``        ``--preset`` / ``--params`` / ``--set`` and the execution-plan options
``guard``          the memory guard, in the command line's terms
``match``          ``sswjax match``: one pair (``folders``: two folders)
``folders``        ``sswjax match LEFT_DIR RIGHT_DIR``
``confidence``     ``match``'s confidence and validity outputs
``geometry``       ``match``'s depth, point cloud and KITTI outputs
``demo``           ``sswjax demo``
``evaluate``       ``sswjax evaluate``, with ``--resume``
``download``       ``sswjax download``
``params``         ``sswjax params``: parameters as JSON, ``--list`` the stages
=================  ==============================================================================
"""

from sswjax.cli.app import console, main

__all__ = ["console", "main"]
