"""Infrastructure for evaluation: metrics (``metrics``), running methods over scenes and
summarising them (``runner``), named methods (``methods``), other projects' matchers (``peers``),
figures (``figures``) and the held-out rule that chose the presets' values (``selection``)."""
