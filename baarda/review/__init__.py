"""`baarda review`: the operator's loop in the browser (docs/review.md)."""
