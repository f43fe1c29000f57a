"""Infrastructure for data: image and PFM files (``io``), data set layouts (``datasets``) and
their download (``download``)."""
