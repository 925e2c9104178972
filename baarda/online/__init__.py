"""On-line quality control of a growing bundle block (docs/online.md, "The growing bundle")."""
