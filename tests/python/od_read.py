"""python canopen's reading of a vendor's EDS/DCF, as a user of python canopen 2.4.1 gets it.

`read_od(path, node_id)` is `canopen.import_od(path, node_id)`, except for a file whose
`[Comments]` section python canopen cannot read: canopen/objectdictionary/eds.py reads the
keys `Line1`..`LineN` of `Lines=N` and raises configparser.NoOptionError on the first one
missing (AMD's Kria KD240 `foc-mc.eds` writes `Lines1=`..`Lines4=`). `[Comments]` is free
text that describes no object, so such a file is read without that section, as a user of
python canopen must edit it to load it at all; that is said on stderr. Any other error of
python canopen's is raised as it is. Our own reader reads the file as it is (with a warning:
protocol/src/od/eds). A copy of this function is in protocol/tests/python/compare_eds.py.
"""
import configparser
import io
import sys

import canopen


def without_comments(text):
    """The file's text without its [Comments] section (every other line as it is)."""
    out, skip = [], False
    for line in text.splitlines(keepends=True):
        s = line.strip()
        if s.startswith("[") and s.endswith("]"):
            skip = s.lower() == "[comments]"
        if not skip:
            out.append(line)
    return "".join(out)


def read_od(path, node_id):
    """python canopen's object dictionary of `path` for `node_id` (see the module's doc)."""
    try:
        return canopen.import_od(path, node_id)
    except configparser.NoOptionError as e:
        if e.section != "Comments":
            raise
        missing = e.option
    with open(path) as f:
        text = without_comments(f.read())
    print(
        f"{path}: python canopen cannot read its [Comments] (no key {missing!r}): "
        "read without that section",
        file=sys.stderr,
    )
    source = io.StringIO(text)
    source.name = path  # import_od takes the format from the name's suffix
    return canopen.import_od(source, node_id)
