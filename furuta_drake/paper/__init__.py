"""The paper's experiments: ``furuta-drake reproduce`` (:mod:`.reproduce`, its report :mod:`.report`), the
observer metrics of Tables I-II (:mod:`.metrics`), the stability analysis of the adaptive loop
(:mod:`.stability`) and the studies of the paper's open problems (:mod:`.studies`)."""
