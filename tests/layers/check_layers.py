#!/usr/bin/env python3
"""The layer rules of docs/ARCHITECTURE.md, checked on the source tree (ctest `layers`).

The dependencies each module declares in its src/<module>/CMakeLists.txt (sparseloop::<m> in
sparseloop_add_module / target_link_libraries) are the one statement of the layering. This check
fails when:
  - a module's declared dependencies are not all listed before it in SPARSELOOP_MODULES (the
    top-level CMakeLists.txt: "a module only links modules listed before it"), or form a cycle;
  - a public header (include/sparseloop/<m>/) or a source file (src/<m>/) includes
    "sparseloop/<x>/..." or a module-internal "<x>/..." header of a module x that <m> does not
    depend on (directly or through the modules it depends on);
  - a public header includes a module-internal header (src/) at all;
  - a module includes <opencv2/...> or <ceres/...> although neither it nor a module it depends on
    links OpenCV / Ceres (so core, io, eval, search, map and posegraph stay OpenCV-free);
  - a public header includes <opencv2/...> or <ceres/...> although the library is not a PUBLIC
    dependency of its module or of a module it depends on (a private dependency stays out of the
    headers a caller compiles: posegraph links Ceres privately, so its public headers are
    Ceres-free).
Usage: check_layers.py [SOURCE_DIR]
"""
import pathlib
import re
import sys


def modules_in_order(root):
    text = (root / "CMakeLists.txt").read_text()
    m = re.search(r"set\(SPARSELOOP_MODULES ([^)]*)\)", text)
    if not m:
        sys.exit("check_layers: no set(SPARSELOOP_MODULES ...) in CMakeLists.txt")
    return m.group(1).split()


THIRD_PARTY = {"opencv2": re.compile(r"opencv_\w+|OpenCV_LIBS"), "ceres": re.compile(r"Ceres::")}


def public_part(call, body):
    """The PUBLIC part of a sparseloop_add_module / target_link_libraries argument list."""
    key = "PUBLIC_DEPS" if call == "sparseloop_add_module" else "PUBLIC"
    m = re.search(rf"\b{key}\b(.*?)(?=\b(PRIVATE_DEPS|PRIVATE|INTERFACE|SOURCES)\b|$)", body, re.S)
    return m.group(1) if m else ""


def declared_deps(root, module, public_only=False):
    """The sparseloop modules `module` links, plus "<opencv2>" / "<ceres>" for those libraries;
    with public_only, only what it links PUBLIC."""
    path = root / "src" / module / "CMakeLists.txt"
    if not path.exists():
        return None
    text = re.sub(r"#[^\n]*", "", path.read_text())
    deps = set()
    # sparseloop_add_module(NAME <module> ...) and target_link_libraries(sparseloop_<module> ...)
    for call in re.finditer(r"(sparseloop_add_module|target_link_libraries)\s*\(([^)]*)\)", text):
        body = call.group(2)
        if call.group(1) == "sparseloop_add_module" and not re.search(rf"NAME\s+{module}\b", body):
            continue
        if call.group(1) == "target_link_libraries" and not re.match(rf"\s*sparseloop_{module}\b",
                                                                     body):
            continue
        if public_only:
            body = public_part(call.group(1), body)
        deps |= set(re.findall(r"sparseloop::(\w+)", body))
        deps |= {f"<{lib}>" for lib, token in THIRD_PARTY.items() if token.search(body)}
    deps.discard(module)
    return deps


def closure(module, deps):
    seen, todo = set(), list(deps.get(module, ()))
    while todo:
        d = todo.pop()
        if d not in seen:
            seen.add(d)
            todo.extend(deps.get(d, ()))
    return seen


def main():
    root = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else ".").resolve()
    order = modules_in_order(root)
    deps = {m: d for m in order if (d := declared_deps(root, m)) is not None}
    public = {m: declared_deps(root, m, public_only=True) for m in deps}
    errors = []
    for m, ds in deps.items():
        for d in sorted(ds):
            if d.startswith("<"):
                continue
            if d not in order:
                errors.append(f"src/{m}/CMakeLists.txt: links sparseloop::{d}, not a module")
            elif order.index(d) >= order.index(m):
                errors.append(f"src/{m}/CMakeLists.txt: links sparseloop::{d}, which is listed "
                              f"after {m} in SPARSELOOP_MODULES")
    include_re = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)
    system_re = re.compile(r'^\s*#\s*include\s+<(opencv2|ceres)/', re.M)
    checked = 0
    for m in deps:
        allowed = closure(m, deps) | {m}
        public_allowed = set().union(*(public[x] for x in (closure(m, public) | {m}) if x in public))
        files = [("include", p) for p in (root / "include" / "sparseloop" / m).rglob("*.h")]
        files += [("src", p) for p in (root / "src" / m).rglob("*") if p.suffix in (".h", ".cc")]
        for kind, path in files:
            checked += 1
            rel = path.relative_to(root)
            text = path.read_text(errors="replace")
            for lib in sorted(set(system_re.findall(text))):
                if f"<{lib}>" not in allowed:
                    errors.append(f"{rel}: includes <{lib}/...>, but {m} links no {lib} "
                                  f"(src/{m}/CMakeLists.txt)")
                elif kind == "include" and f"<{lib}>" not in public_allowed:
                    errors.append(f"{rel}: public header includes <{lib}/...>, but {m} links "
                                  f"{lib} only privately (src/{m}/CMakeLists.txt)")
            for inc in include_re.findall(text):
                parts = inc.split("/")
                if parts[0] == "sparseloop" and len(parts) > 2:
                    target = parts[1]
                elif parts[0] in deps and len(parts) > 1:
                    target = parts[0]  # a module-internal header, src/<x>/...
                    if kind == "include":
                        errors.append(f"{rel}: public header includes the internal \"{inc}\"")
                        continue
                else:
                    continue
                if target in deps and target not in allowed:
                    errors.append(f"{rel}: includes \"{inc}\", but {m} does not depend on "
                                  f"{target} (src/{m}/CMakeLists.txt)")
    if checked == 0:
        errors.append("no source files found: wrong SOURCE_DIR?")
    for e in errors:
        print("layer violation:", e)
    print(f"check_layers: {len(deps)} modules, {checked} files, {len(errors)} violations")
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
