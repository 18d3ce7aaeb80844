"""Analysis of shared-control studies: tidy data, the paper's statistics, figures and reports."""
