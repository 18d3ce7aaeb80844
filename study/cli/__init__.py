"""``python -m study COMMAND`` subcommands; each module has ``add_arguments`` and ``main``.

    schedule   print the counterbalanced trial schedule (study.cli.schedule)
    export     write tidy CSV + Parquet tables and a codebook from a store (study.cli.export)
"""
