"""Infrastructure for evaluation: metrics (``metrics``), running methods over scenes and
summarising them (``runner``), named methods (``methods``), other projects' matchers (``peers``)
and figures (``figures``)."""
