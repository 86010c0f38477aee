"""The files a batch keeps in OUTDIR beside the clips' outputs. No clip's output may take one of
these names (:mod:`.jobs` gives such a clip another name)."""
SUMMARY_NAME = "summary.csv"
INDEX_NAME = "index.html"
MANIFEST_NAME = ".retime-batch.json"
LOCK_NAME = ".retime-batch.lock"
BATCH_FILES = (SUMMARY_NAME, INDEX_NAME, MANIFEST_NAME, LOCK_NAME)
OUTPUT_SUFFIXES = (".bvh", ".csv", ".json", ".png")  # what any method writes per clip
