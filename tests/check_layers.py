#!/usr/bin/env python3
"""The layering check (docs/design.md, "Layers"): every module of the library is one CMake target,
and a file of a module includes only its own module and the modules its target links directly.

    check_layers.py SOURCE_DIR LAYERS_FILE     check the tree against the build's link graph
    check_layers.py --self-test                show that each rule fails on a tree that breaks it

LAYERS_FILE is written by src/CMakeLists.txt at configure time (build/sonar3d_layers.txt), from the
targets themselves, one module a line:

    <module> public: <modules linked PUBLIC> private: <modules linked PRIVATE>

Rules, with no exception list:
  1. every directory of src/ and include/sonar3d/ is a module with a target, and every module
     target has a directory;
  2. the link graph between modules has no cycle (lower layers never link higher ones);
  3. a file in src/<m>/ or include/sonar3d/<m>/ includes (#include "sonar3d/<x>/...", or a relative
     path into src/<x>/) only modules that sonar3d_<m> links directly;
  4. a public header (include/sonar3d/<m>/) includes only modules that sonar3d_<m> links PUBLIC,
     since whoever includes the header compiles theirs too.
"""
import os
import re
import shutil
import sys
import tempfile

INCLUDE_RE = re.compile(r'^\s*#\s*include\s*([<"])([^>"]+)[>"]')
SOURCE_EXT = (".cpp", ".cc", ".cxx", ".hpp", ".h", ".hh", ".inl", ".ipp")
# Files directly in include/sonar3d/ (version.hpp, generated into the build tree) belong to core,
# whose target carries the generated include directory.
TOP_LEVEL_OWNER = "core"


def read_layers(path):
    """{module: (public set, private set)} from the file src/CMakeLists.txt writes."""
    layers = {}
    with open(path, encoding="utf-8") as f:
        for n, line in enumerate(f, 1):
            line = line.strip()
            if not line or line.startswith("#"):
                continue
            m = re.match(r"^(\w+)\s+public:(.*?)\s+private:(.*)$", line)
            if not m:
                raise SystemExit("%s:%d: cannot parse '%s'" % (path, n, line))
            layers[m.group(1)] = (set(m.group(2).split()), set(m.group(3).split()))
    return layers


def subdirs(path):
    if not os.path.isdir(path):
        return set()
    return {d for d in os.listdir(path) if os.path.isdir(os.path.join(path, d))}


def module_files(root, module):
    """(path, is_public_header) for every source file of a module."""
    for base, public in ((os.path.join(root, "src", module), False),
                         (os.path.join(root, "include", "sonar3d", module), True)):
        for dirpath, _, files in os.walk(base):
            for name in sorted(files):
                if name.endswith(SOURCE_EXT):
                    yield os.path.join(dirpath, name), public


def included_module(root, including_file, bracket, target):
    """The module a file's #include names, or None (the standard library, a dependency)."""
    parts = target.split("/")
    if parts[0] == "sonar3d":
        return parts[1] if len(parts) > 2 else TOP_LEVEL_OWNER
    if bracket == '"':
        # Relative to the including file: its own directory, or another module's (../core/x.hpp).
        resolved = os.path.normpath(os.path.join(os.path.dirname(including_file), target))
        for base in (os.path.join(root, "src"), os.path.join(root, "include", "sonar3d")):
            rel = os.path.relpath(resolved, base)
            if not rel.startswith("..") and os.sep in rel:
                return rel.split(os.sep)[0]
    return None


def find_cycle(graph):
    """A list of modules forming a cycle of the link graph, or None."""
    state = {}

    def visit(node, stack):
        state[node] = "open"
        stack.append(node)
        for dep in sorted(graph.get(node, ())):
            if state.get(dep) == "open":
                return stack[stack.index(dep):] + [dep]
            if dep not in state:
                found = visit(dep, stack)
                if found:
                    return found
        stack.pop()
        state[node] = "done"
        return None

    for node in sorted(graph):
        if node not in state:
            found = visit(node, [])
            if found:
                return found
    return None


def check(root, layers):
    """The list of violations (empty: the layering holds)."""
    errors = []
    modules = set(layers)
    dirs = subdirs(os.path.join(root, "src")) | subdirs(os.path.join(root, "include", "sonar3d"))
    for d in sorted(dirs - modules):
        errors.append("src/%s or include/sonar3d/%s has no module target sonar3d_%s "
                      "(add src/%s/CMakeLists.txt and list it in src/CMakeLists.txt)" %
                      (d, d, d, d))
    for m in sorted(modules - dirs):
        errors.append("module target sonar3d_%s has no directory src/%s" % (m, m))
    graph = {m: pub | priv for m, (pub, priv) in layers.items()}
    for m, deps in sorted(graph.items()):
        for d in sorted(deps - modules):
            errors.append("sonar3d_%s links sonar3d_%s, which is not a module" % (m, d))
    cycle = find_cycle(graph)
    if cycle:
        errors.append("the modules link in a cycle: " + " -> ".join(cycle) +
                      " (lower layers never link higher ones)")
    for m in sorted(modules & dirs):
        public, private = layers[m]
        for path, is_public_header in module_files(root, m):
            with open(path, encoding="utf-8", errors="replace") as f:
                for n, line in enumerate(f, 1):
                    inc = INCLUDE_RE.match(line)
                    if not inc:
                        continue
                    x = included_module(root, path, inc.group(1), inc.group(2))
                    if x is None or x == m:
                        continue
                    where = "%s:%d" % (os.path.relpath(path, root), n)
                    if x not in public | private:
                        errors.append("%s includes %s (module %s), but sonar3d_%s does not link "
                                      "sonar3d_%s" % (where, inc.group(2), x, m, x))
                    elif is_public_header and x not in public:
                        errors.append("%s: a public header includes %s (module %s), but "
                                      "sonar3d_%s links sonar3d_%s PRIVATE (make it PUBLIC)" %
                                      (where, inc.group(2), x, m, x))
    return errors


def self_test():
    """Each rule, broken once in a small tree, must be reported; the unbroken tree must pass."""
    def make_tree(files):
        root = tempfile.mkdtemp(prefix="check_layers_")
        for rel, text in files.items():
            path = os.path.join(root, rel)
            os.makedirs(os.path.dirname(path), exist_ok=True)
            with open(path, "w", encoding="utf-8") as f:
                f.write(text)
        return root

    good_files = {
        "src/core/a.cpp": '#include "sonar3d/core/a.hpp"\n#include "internal.hpp"\n',
        "src/core/internal.hpp": "#include <vector>\n",
        "include/sonar3d/core/a.hpp": "#include <Eigen/Core>\n",
        "src/io/b.cpp": '#include "sonar3d/io/b.hpp"\n#include "../core/internal.hpp"\n'
                        '#include "sonar3d/version.hpp"\n',
        "include/sonar3d/io/b.hpp": '#include "sonar3d/core/a.hpp"\n',
    }
    good_layers = {"core": (set(), set()), "io": ({"core"}, set())}
    cases = [
        ("the layered tree", good_files, good_layers, None),
        ("an include up the layers", dict(good_files, **{
            "src/core/c.cpp": '#include "sonar3d/io/b.hpp"\n'}), good_layers, "does not link"),
        ("a relative include into another module", dict(good_files, **{
            "src/core/c.cpp": '#include "../io/private.hpp"\n',
            "src/io/private.hpp": ""}), good_layers, "does not link"),
        ("a cycle", good_files, {"core": (set(), {"io"}), "io": ({"core"}, set())}, "cycle"),
        ("a public header needing a private link", good_files,
         {"core": (set(), set()), "io": (set(), {"core"})}, "PRIVATE"),
        ("a directory without a target", dict(good_files, **{"src/extra/x.cpp": ""}),
         good_layers, "no module target"),
        ("a target without a directory", good_files,
         dict(good_layers, extra=(set(), set())), "no directory"),
    ]
    failed = False
    for name, files, layers, expect in cases:
        root = make_tree(files)
        try:
            errors = check(root, layers)
        finally:
            shutil.rmtree(root)
        ok = not errors if expect is None else any(expect in e for e in errors)
        print("self-test %-45s %s" % (name + ":", "ok" if ok else "FAILED %s" % errors))
        failed |= not ok
    return 1 if failed else 0


def main(argv):
    if argv[1:] == ["--self-test"]:
        return self_test()
    if len(argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    root, layers_file = argv[1], argv[2]
    layers = read_layers(layers_file)
    errors = check(root, layers)
    for e in errors:
        print(e, file=sys.stderr)
    if errors:
        print("layering check: %d violation(s) (docs/design.md, \"Layers\")" % len(errors),
              file=sys.stderr)
        return 1
    print("layering check: %d modules, no include runs up the layers" % len(layers))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
