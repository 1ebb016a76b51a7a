"""python canopen's reading of a vendor's EDS/DCF, as a user of python canopen 2.4.1 gets it.

`read_od(path, node_id)` is `canopen.import_od(path, node_id)`, except for a file whose
`[Comments]` section python canopen cannot read: canopen/objectdictionary/eds.py reads the
keys `Line1`..`LineN` of `Lines=N` and raises configparser.NoOptionError on the first one
missing (AMD's Kria KD240 `foc-mc.eds` writes `Lines1=`..`Lines4=`). `[Comments]` is free
text that describes no object, so such a file is read without that section, as a user of
python canopen must edit it to load it at all; that is said on stderr. Any other error of
python canopen's is raised as it is. Our own reader reads the file as it is (with a warning:
protocol/src/od/eds). protocol/tests/python/compare_eds.py imports it too.
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


def not_downloaded(path):
    """The (index, sub) of `path` whose ObjFlags has bit 0 set: CiA 306 says the value is not
    written to the device when the file is downloaded (maxon's EPOS4 DCFs set it on values read
    from the drive that are no configuration: 0x1003:0, 0x1010:1, the identity). python
    canopen 2.4.1 reads no ObjFlags: its load_configuration() writes them all (0x1010:1 = 1 is
    refused 0x08000020 by a CiA 301 device, 0x1003:0 = 1 0x06090030)."""
    eds = configparser.RawConfigParser(inline_comment_prefixes=(";",), strict=False)
    eds.optionxform = str
    with open(path) as f:
        eds.read_file(f)
    out = set()
    for section in eds.sections():
        name = section.upper()
        index, _, sub = name.partition("SUB")
        if len(index) != 4 or not eds.has_option(section, "ObjFlags"):
            continue
        try:
            flags = int(eds.get(section, "ObjFlags"), 0)
            key = (int(index, 16), int(sub, 16) if sub else 0)
        except ValueError:
            continue
        if flags & 1:
            out.add(key)
    return out


def honour_objflags(od, path):
    """Before load_configuration(): the values `path` marks not to be downloaded (ObjFlags bit
    0) taken out of `od` (python canopen's reading of it), as a master that honours CiA 306's
    ObjFlags leaves them; PDO parameters stay (python canopen writes those through its PDO
    maps). The (index, sub) taken out, sorted."""
    taken = []
    for index, sub in sorted(not_downloaded(path)):
        if 0x1400 <= index < 0x1C00 or index not in od:
            continue
        obj = od[index]
        var = obj if not hasattr(obj, "subindices") else obj.subindices.get(sub)
        if var is not None and getattr(var, "value", None) is not None:
            var.value = None
            taken.append((index, sub))
    return taken
