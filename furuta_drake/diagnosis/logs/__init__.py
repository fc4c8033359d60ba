"""Reading the logs (stage 1): the log format (:mod:`.format`), the CSV, Parquet and MCAP readers
(:mod:`.readers`) and the CSV writer (:mod:`.writers`), several runs in one file (:mod:`.run_column`), and the
checked ``RunLog`` with the rig file's direction checks (:mod:`.load`). Imports nothing else of the diagnosis but
its settings."""
