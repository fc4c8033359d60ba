"""Writing the report: ``report.json``, ``report.md``, ``report.html`` and the plots (:mod:`.files`), the words
(:mod:`.narrative`, and the text keys of ``report.json`` in :mod:`.record_text`), the tables and charts
(:mod:`.tables`, :mod:`.charts`, :mod:`.html`) and the torque beyond the vocabulary (:mod:`.torque`). Reads what the
earlier stages decided; computes no verdict."""
