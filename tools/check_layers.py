#!/usr/bin/python3
"""The layer rule of docs/architecture.md ("Layers"), checked on what the compiler sees.

The physics folders (src/mesh, src/model, src/collide, src/contact, src/scene) and the
serial stepper (src/step) may include the data layer and each other, never a header of
the layers above them (src/sim, src/app, src/io, src/parallel, and the public headers
those own), nor MPI or PETSc: the physics must build and run without a communicator. For every source file of
those folders in the build's compile_commands.json, the compiler lists the headers it
includes, transitively (-M with the file's own flags); any forbidden one fails the check,
with the file and the header named.

usage: check_layers.py BUILD_DIR
"""
import json
import os
import re
import shlex
import subprocess
import sys

PHYSICS = re.compile(r"^src/(mesh|model|collide|contact|scene|step)/")
# Public headers of the upper layers (include/softcontact/): parallel, sim, io, app.
UPPER = ("halo", "partition", "mpi_util", "simulator", "integrator", "implicit_euler", "run",
         "checkpoint", "frame_writer", "diagnostics", "memory", "bench", "cli")
FORBIDDEN = re.compile(r"(/mpi\.h$|/petsc[^/]*\.h$|/include/softcontact/(" + "|".join(UPPER) +
                       r")\.hpp$|/src/(sim|app|io|parallel)/)")


def main():
    if len(sys.argv) != 2:
        print(__doc__.strip().splitlines()[-1], file=sys.stderr)
        return 2
    build = sys.argv[1]
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    path = os.path.join(build, "compile_commands.json")
    try:
        with open(path) as f:
            commands = json.load(f)
    except (OSError, ValueError) as e:
        print(f"check_layers: cannot read {path}: {e}", file=sys.stderr)
        return 2
    checked, bad = 0, 0
    for e in commands:
        src = os.path.realpath(e["file"])
        rel = os.path.relpath(src, root)
        if not PHYSICS.match(rel):
            continue
        args = shlex.split(e["command"]) if "command" in e else list(e["arguments"])
        cmd, skip = [], False
        for a in args:
            if skip:
                skip = False
            elif a == "-o":
                skip = True
            elif a != "-c" and os.path.realpath(os.path.join(e["directory"], a)) != src:
                cmd.append(a)
        r = subprocess.run(cmd + ["-M", src], cwd=e["directory"], capture_output=True, text=True)
        if r.returncode != 0:
            print(f"check_layers: the compiler failed on {rel}:\n{r.stderr}", file=sys.stderr)
            return 2
        deps = r.stdout.replace("\\\n", " ").split()[1:]
        hits = sorted({os.path.realpath(d) for d in deps if FORBIDDEN.search(os.path.realpath(d))})
        checked += 1
        for h in hits:
            bad += 1
            print(f"{rel}: includes {os.path.relpath(h, root) if h.startswith(root) else h}")
    if checked == 0:
        print("check_layers: no source file of the physics folders in compile_commands.json", file=sys.stderr)
        return 2
    print(f"check_layers: {checked} source files of src/{{mesh,model,collide,contact,scene,step}}, "
          f"{bad} forbidden includes")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
