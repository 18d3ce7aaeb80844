"""``python -m study COMMAND`` subcommands, one module each with ``add_arguments(parser)`` and
``main(args) -> int`` (dispatched by ``study.cli.dispatch``, see ``study/__main__.py``):

    serve      the study server: participant page on the LAN, experimenter console on 127.0.0.1
    trial      one headless trial, its outcome as JSON
    render     a trial to MP4, live or replayed from saved records or a store
    schedule   the counterbalanced trial schedule (study.schedule) as CSV or JSON
    run        one whole session headless with a scripted participant
    simulate   simulated participants through the whole study
    sweep      the arbitration modes calibrated by the paper's criteria (study.sweep)
    export     tidy CSV + Parquet tables, codebook and metadata from a store (study.export)
    retention  record a data-retention answer given in person after a session stopped
    salvage    what is readable of a damaged store, copied into a new store (study.store.salvage)
"""
