#!/usr/bin/env python3
"""Adversarial trial (issue 17): thousands of hostile or mutated inputs through every vizsim
command, each with a timeout and an address-space limit, counting what must never happen.

    cargo build --release
    scripts/adversarial-trial.py [--count 3000] [--seed 17] [--jobs 2] [--bin target/release/vizsim]

Inputs are mutations of the project's own valid files (the preset hardware configuration,
transfer functions, experiment files, camera paths) and of small valid volumes (NRRD headers,
raw files and their names, descriptors), result folders, PNG images, hostile command-line
numbers, and special files (FIFOs, /dev/zero, folders, symlink loops) as inputs, devices,
symlinks and folders as outputs. Each run gets a fresh folder, VIZSIM_MEMORY_BUDGET=512M, an
address-space limit of 4 GiB (RLIMIT_AS) and a timeout. Counted:

- panics: exit 101 or "panicked" on stderr;
- hangs: still running at the timeout (killed);
- aborts: ended by a signal (SIGABRT from a failed allocation, SIGSEGV, ...);
- files left: after a failed run, an output it was asked to write that did not exist before,
  or a hidden `.NAME.tmpPID` temporary anywhere in its folder (after any run).

Runs that succeed (a mutation can be valid) or fail cleanly are fine. Every bad case is kept
under OUT/bad/ with its command line and stderr. Exit status 1 when any count is not 0.
"""

import argparse
import gzip
import os
import random
import resource
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time
import zlib
from concurrent.futures import ThreadPoolExecutor

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

HOSTILE_NUMBERS = [
    "0", "-1", "1", "-0", "nan", "NaN", "inf", "-inf", "1e308", "1e-308", "5e-324", "3e38",
    "1e-38", "18446744073709551615", "18446744073709551616", "9223372036854775807",
    "-9223372036854775808", "4294967295", "4294967296", "65535", "65536", "99999999999999999999",
    "0x10", "1_000", "", " ", "1.5", "0.0", "1e9", "2147483648", "256", "3", "7",
]
HOSTILE_WORDS = [
    '""', '"x"', "[]", "{}", "[[]]", "true", "false", '"\\u0000"', "[1, [2, [3]]]",
    '"' + "A" * 5000 + '"', "{a = 1}", '"nan"', "[nan]", "[inf, -inf]",
]
SPECIAL = ["fifo", "zero", "folder", "missing", "loop", "dangling", "full", "null"]


def mutate_text(text, rng):
    """One to three line-level mutations of a TOML or header text."""
    lines = text.split("\n")
    for _ in range(rng.randint(1, 3)):
        if not lines:
            lines = [""]
        i = rng.randrange(len(lines))
        op = rng.random()
        line = lines[i]
        if op < 0.45 and "=" in line or op < 0.45 and ":" in line:
            sep = "=" if "=" in line else ":"
            key = line.split(sep, 1)[0]
            value = rng.choice(HOSTILE_NUMBERS + HOSTILE_WORDS)
            lines[i] = f"{key}{sep} {value}"
        elif op < 0.55:
            del lines[i]
        elif op < 0.62:
            lines.insert(i, line)
        elif op < 0.7:
            lines[i] = line[: rng.randrange(len(line) + 1)]
        elif op < 0.76:
            lines.insert(i, "[" + rng.choice(["bogus", "memory", "x.y", "", "[a]"]) + "]")
        elif op < 0.82:
            lines.insert(i, rng.choice(["x = 1", "= 1", "a.b.c = [", '"k" = {', "#" * 2000]))
        elif op < 0.88:
            # Numbers in the line replaced by extreme ones.
            words = line.split(" ")
            for j, w in enumerate(words):
                if w.strip(",[]").replace(".", "", 1).lstrip("-").isdigit():
                    words[j] = rng.choice(HOSTILE_NUMBERS)
            lines[i] = " ".join(words)
        elif op < 0.94:
            j = rng.randrange(len(lines))
            lines[i], lines[j] = lines[j], lines[i]
        else:
            lines = lines[:i]
    out = "\n".join(lines)
    if rng.random() < 0.05:
        b = bytearray(out.encode())
        for _ in range(rng.randint(1, 8)):
            if b:
                b[rng.randrange(len(b))] = rng.randrange(256)
        return bytes(b)
    return out.encode()


def make_special(path, kind):
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "zero":
        os.symlink("/dev/zero", path)
    elif kind == "folder":
        os.makedirs(path)
    elif kind == "loop":
        os.symlink(path, path)
    elif kind == "dangling":
        os.symlink(path + ".nowhere/x", path)
    elif kind == "full":
        os.symlink("/dev/full", path)
    elif kind == "null":
        os.symlink("/dev/null", path)


def png_bytes(w, h):
    raw = b"".join(b"\x00" + bytes([(x * 40 + y) % 256 for x in range(w) for _ in range(4)]) for y in range(h))
    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xFFFFFFFF)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 6, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def read(rel):
    with open(os.path.join(ROOT, rel), "r", encoding="utf-8") as f:
        return f.read()


class Gen:
    """Builds one case in a folder: files, argv, the outputs it must not leave on failure."""

    def __init__(self, rng):
        self.rng = rng
        self.config = read("configs/hardware/vizard2.toml")
        tdir = os.path.join(ROOT, "configs/transfer")
        self.tfs = [read(os.path.join("configs/transfer", f)) for f in sorted(os.listdir(tdir))]
        edir = os.path.join(ROOT, "configs/experiments")
        self.experiments = [read(os.path.join("configs/experiments", f)) for f in sorted(os.listdir(edir))]
        self.paths = [read("configs/paths/tube.toml"), read("configs/paths/aneurism.toml")]
        self.small_experiment = (
            'name = "t"\ndatasets = ["phantom:sphere:8"]\ntf = ["zero", "class"]\n'
            'modes = ["none", "ert+leap4"]\nmodels = ["step", "cycle"]\n[frames]\norbit = 4\n'
            'select = [0, 1]\nsize = "8x8"\n[axes]\n"ray_queue.rays" = [8, 16]\n'
        )

    def frame_command(self, d, extra, outputs=True):
        rng = self.rng
        cmd = rng.choice(["render", "render-fixed", "sim", "occupancy", "update", "sequence", "precision"])
        o = lambda n: os.path.join(d, n)
        if cmd == "render":
            return ["render", "--dataset", "phantom:sphere:8", "--size", "8x8", "-o", o("x.png")] + extra, [o("x.png")]
        if cmd == "render-fixed":
            return (["render", "--model", "fixed", "--dataset", "phantom:sphere:8", "--size", "8x8", "-o", o("x.png"),
                     "--json", o("x.json")] + extra, [o("x.png"), o("x.json")])
        if cmd == "sim":
            return (["sim", "--dataset", "phantom:sphere:8", "--size", "8x8", "-o", o("s.png"), "--json", o("s.json")]
                    + extra, [o("s.png"), o("s.json")])
        if cmd == "occupancy":
            return ["occupancy", "phantom:sphere:8"] + extra, []
        if cmd == "update":
            return ["update", "phantom:sphere:8", "--subcube", "4"] + extra, []
        if cmd == "sequence":
            return ["sequence", "--source", "phantom:metaballs:8", "--steps", "2", "--size", "8x8", "--subcube", "4"] + extra, []
        return ["precision", "--dataset", "phantom:sphere:8", "--size", "8x8", "--out", o("p")] + extra, [o("p")]

    def case(self, d):
        rng = self.rng
        kind = rng.choices(
            ["config", "tf", "experiment", "experiment-run", "nrrd", "raw", "descriptor", "path",
             "numbers", "special-input", "special-output", "results", "image", "set"],
            weights=[12, 10, 10, 5, 12, 6, 6, 5, 10, 8, 6, 6, 4, 6])[0]
        o = lambda n: os.path.join(d, n)
        if kind == "config":
            with open(o("hw.toml"), "wb") as f:
                f.write(mutate_text(self.config, rng))
            argv, outs = self.frame_command(d, ["--config", o("hw.toml")])
            return kind, argv, outs
        if kind == "set":
            field = rng.choice([l.split("=")[0].strip() for l in self.config.split("\n")
                                if "=" in l and not l.startswith("#")] + ["a.b", "memory", ""])
            section = ""
            for l in self.config.split("\n"):
                if l.startswith("["):
                    section = l.strip("[] ")
                if l.split("=")[0].strip() == field and section:
                    field = section + "." + field
                    break
            argv, outs = self.frame_command(d, ["--set", f"{field}={rng.choice(HOSTILE_NUMBERS + HOSTILE_WORDS)}"])
            return kind, argv, outs
        if kind == "tf":
            with open(o("tf.toml"), "wb") as f:
                f.write(mutate_text(rng.choice(self.tfs), rng))
            argv, outs = self.frame_command(d, ["--tf", o("tf.toml")])
            return kind, argv, outs
        if kind in ("experiment", "experiment-run"):
            base = rng.choice(self.experiments) if kind == "experiment" else self.small_experiment
            with open(o("e.toml"), "wb") as f:
                f.write(mutate_text(base, rng))
            argv = ["sweep", o("e.toml"), "--out", o("out")]
            if kind == "experiment" or rng.random() < 0.3:
                argv.append("--dry-run")
            if rng.random() < 0.2:
                argv += ["--shard", rng.choice(["0/2", "1/2", "5/3", "x", "0/0", "1/18446744073709551616"])]
            return kind, argv, [o("out")]
        if kind == "nrrd":
            n = 4
            header = ("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nspacings: 1 1 1\n"
                      f"endian: little\nencoding: {rng.choice(['raw', 'gzip'])}\n")
            detached = rng.random() < 0.3
            payload = bytes(range(n ** 3))
            if "gzip" in header:
                payload = gzip.compress(payload)
            if rng.random() < 0.3:
                payload = payload[: rng.randrange(len(payload) + 1)] + os.urandom(rng.randrange(8))
            if detached:
                header += "data file: d.raw\n"
                text = mutate_text(header, rng) + b"\n"
                with open(o("v.nhdr"), "wb") as f:
                    f.write(text)
                if rng.random() < 0.2:
                    make_special(o("d.raw"), rng.choice(SPECIAL[:5]))
                else:
                    with open(o("d.raw"), "wb") as f:
                        f.write(payload)
                path = o("v.nhdr")
            else:
                with open(o("v.nrrd"), "wb") as f:
                    f.write(mutate_text(header, rng) + b"\n" + payload)
                path = o("v.nrrd")
            return kind, self.volume_command(d, path), [o("x.png"), o("s.png")]
        if kind == "raw":
            dims = [rng.choice(["4", "0", "1", "8", "99999", "18446744073709551615", "-4", "4.5"]) for _ in range(3)]
            name = f"v_{'x'.join(dims)}_{rng.choice(['uint8', 'uint16', 'float', 'uint8'])}.raw"
            size = rng.choice([0, 1, 63, 64, 65, 128, 512, 4096])
            with open(o(name), "wb") as f:
                f.write(os.urandom(size))
            if rng.random() < 0.5:
                return kind, self.volume_command(d, o(name)), [o("x.png"), o("s.png")]
            os.makedirs(o("data"))
            os.rename(o(name), os.path.join(o("data"), name))
            return kind, ["info", "v", "--data-dir", o("data")], []
        if kind == "descriptor":
            with open(o("d.raw"), "wb") as f:
                f.write(bytes(64))
            base = ('name = "v"\nfile = "d.raw"\ndims = [4, 4, 4]\ntype = "uint8"\nspacing = [1.0, 1.0, 1.0]\n'
                    'endian = "little"\n')
            with open(o("v.toml"), "wb") as f:
                f.write(mutate_text(base, rng))
            return kind, self.volume_command(d, o("v.toml")), [o("x.png"), o("s.png")]
        if kind == "path":
            with open(o("p.toml"), "wb") as f:
                f.write(mutate_text(rng.choice(self.paths), rng))
            k, n = rng.choice(["0", "5", "-1", "99", "4294967296"]), rng.choice(["10", "1", "0", "100000"])
            argv = [rng.choice(["render", "sim"]), "--dataset", "phantom:tube:8", "--size", "8x8", "--projection",
                    "persp", "--view", f"path:{o('p.toml')}:{k}/{n}", "-o", o("x.png")]
            return kind, argv, [o("x.png")]
        if kind == "numbers":
            opt = rng.choice(["--size", "--spacing", "--view", "--subcube", "--bricks", "--threads",
                              "--memory-budget", "--ideal-latency", "--trace-cycles", "--steps", "--dt",
                              "--brick", "--dataset"])
            value = rng.choice(HOSTILE_NUMBERS)
            if opt == "--size":
                value = f"{rng.choice(HOSTILE_NUMBERS)}x{rng.choice(HOSTILE_NUMBERS)}"
            elif opt == "--view":
                value = f"orbit:{rng.choice(HOSTILE_NUMBERS)}/{rng.choice(HOSTILE_NUMBERS)}"
            elif opt == "--trace-cycles":
                value = f"{rng.choice(HOSTILE_NUMBERS)}..{rng.choice(HOSTILE_NUMBERS)}"
            elif opt == "--dataset":
                value = f"phantom:{rng.choice(['sphere', 'metaballs', 'tsdf', 'x'])}:{rng.choice(HOSTILE_NUMBERS)}"
            if opt in ("--threads", "--memory-budget"):
                argv = [f"{opt}={value}", "render", "--dataset", "phantom:sphere:8", "--size", "8x8", "-o", o("x.png")]
                return kind, argv, [o("x.png")]
            if opt in ("--steps", "--dt", "--brick"):
                argv = ["sequence", "--source", "phantom:metaballs:8", "--size", "8x8", "--map", "none", f"{opt}={value}"]
                return kind, argv, []
            if opt in ("--ideal-latency", "--trace-cycles"):
                argv = ["sim", "--dataset", "phantom:sphere:8", "--size", "8x8", "--memory", "ideal", f"{opt}={value}",
                        "--command-trace", o("t.csv"), "--vcd", o("w.vcd"), "-o", o("s.png")]
                return kind, argv, [o("t.csv"), o("w.vcd"), o("s.png")]
            argv = [rng.choice(["render", "sim"]), "--dataset", "phantom:sphere:8", "--size", "8x8", "-o", o("x.png")]
            argv = [a for a in argv]
            if opt in argv:
                argv[argv.index(opt) + 1] = value
            else:
                argv.append(f"{opt}={value}")
            return kind, argv, [o("x.png")]
        if kind == "special-input":
            special = rng.choice(SPECIAL[:5] + ["dangling"])
            target = rng.choice(["hw.toml", "tf.toml", "e.toml", "v.nrrd", "v.toml", "p.toml", "a.png"])
            make_special(o(target), special)
            if target == "hw.toml":
                argv, outs = self.frame_command(d, ["--config", o(target)])
            elif target == "tf.toml":
                argv, outs = self.frame_command(d, ["--tf", o(target)])
            elif target == "e.toml":
                argv, outs = ["sweep", o(target), "--out", o("out")] + (["--dry-run"] if rng.random() < 0.5 else []), [o("out")]
            elif target in ("v.nrrd", "v.toml"):
                argv, outs = self.volume_command(d, o(target)), [o("x.png"), o("s.png")]
            elif target == "p.toml":
                argv, outs = ["render", "--dataset", "phantom:sphere:8", "--size", "8x8", "--view",
                              f"path:{o(target)}:0/10", "-o", o("x.png")], [o("x.png")]
            else:
                with open(o("b.png"), "wb") as f:
                    f.write(png_bytes(4, 4))
                argv, outs = ["compare", o(target), o("b.png"), "--json", o("c.json")], [o("c.json")]
            return kind, argv, outs
        if kind == "special-output":
            special = rng.choice(SPECIAL)
            name = rng.choice(["x.png", "x.json", "out"])
            make_special(o(name), special)
            cmd = rng.choice(["render", "sim", "sweep", "merge", "table"])
            if cmd in ("render", "sim"):
                argv = [cmd, "--dataset", "phantom:sphere:8", "--size", "8x8", "-o", o(name), "--json", o("y.json")]
                outs = [o("y.json")]
            elif cmd == "sweep":
                with open(o("e.toml"), "w") as f:
                    f.write(self.small_experiment)
                argv, outs = ["sweep", o("e.toml"), "--out", o(name)], []
            else:
                os.makedirs(o("run"))
                with open(os.path.join(o("run"), "results.jsonl"), "w") as f:
                    f.write('{"key":"a","dataset":"d","tf":"zero","mode":"none","model":"step","frame":0,"fps":1}\n')
                argv = ["merge", o("run"), "--out", o(name)] if cmd == "merge" else ["table", o("run"), "--out", o(name)]
                outs = []
            return kind, argv, outs
        if kind == "results":
            os.makedirs(o("run"))
            lines = []
            for i in range(rng.randint(0, 6)):
                lines.append('{"key":"%016x","experiment":"t","dataset":"phantom:sphere:8","tf":"zero","mode":"none",'
                             '"model":"step","frame":%d,"fps":%s,"steps":%d,"axes":{}}' % (i, i, rng.choice(HOSTILE_NUMBERS[:12] + ["1.5"]), i))
            text = mutate_text("\n".join(lines) + "\n", rng) if rng.random() < 0.7 else ("\n".join(lines) + "\n").encode()
            target = rng.choice(["results.jsonl", "results.jsonl", "timing.jsonl", "experiment.resolved.json"])
            if rng.random() < 0.15:
                make_special(os.path.join(o("run"), target), rng.choice(SPECIAL[:5]))
                if target != "results.jsonl":
                    with open(os.path.join(o("run"), "results.jsonl"), "wb") as f:
                        f.write(text)
            else:
                with open(os.path.join(o("run"), target), "wb") as f:
                    f.write(text)
            cmd = rng.choice(["merge", "table", "plot", "sweep"])
            if cmd == "merge":
                return kind, ["merge", o("run"), "--out", o("m")], [o("m")]
            if cmd in ("table", "plot"):
                return kind, [cmd, o("run"), "--out", o("t")], [o("t")]
            with open(o("e.toml"), "w") as f:
                f.write(self.small_experiment)
            return kind, ["sweep", o("e.toml"), "--out", o("run"), "--dry-run"], []
        # image
        data = bytearray(png_bytes(rng.choice([1, 4, 16]), rng.choice([1, 4, 16])))
        for _ in range(rng.randint(0, 6)):
            data[rng.randrange(len(data))] = rng.randrange(256)
        if rng.random() < 0.2:
            # A header declaring a huge image.
            data[16:24] = struct.pack(">II", rng.choice([65535, 1 << 30, 0x7FFFFFFF]), rng.choice([65535, 1 << 30]))
        with open(o("a.png"), "wb") as f:
            f.write(data)
        with open(o("b.png"), "wb") as f:
            f.write(png_bytes(4, 4))
        return "image", ["compare", o("a.png"), o("b.png"), "--json", o("c.json"), "--diff", o("d.png")], [o("c.json"), o("d.png")]

    def volume_command(self, d, path):
        o = lambda n: os.path.join(d, n)
        tf = o("tf.toml")
        if not os.path.exists(tf):
            shutil.copy(os.path.join(ROOT, "configs/transfer/phantom-sphere-class.toml"), tf)
        return self.rng.choice([
            ["info", path],
            ["render", "--dataset", path, "--size", "8x8", "--tf", tf, "-o", o("x.png")],
            ["sim", "--dataset", path, "--size", "8x8", "--tf", tf, "-o", o("s.png")],
            ["occupancy", path, "--tf", tf],
            ["update", path, "--tf", tf, "--subcube", "4"],
        ])


def limit_memory(bytes_):
    def apply():
        resource.setrlimit(resource.RLIMIT_AS, (bytes_, bytes_))
        os.setsid()
    return apply


def snapshot(d):
    return {os.path.join(r, n) for r, ds, fs in os.walk(d) for n in ds + fs}


def run_case(binary, d, argv, outs, timeout, memory):
    existed = {p for p in outs if os.path.lexists(p)}
    start = time.time()
    proc = subprocess.Popen([binary] + argv, cwd=d, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, preexec_fn=limit_memory(memory),
                            env=dict(os.environ, VIZSIM_MEMORY_BUDGET="512M", RAYON_NUM_THREADS="1"))
    try:
        _, err = proc.communicate(timeout=timeout)
        hung = False
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        _, err = proc.communicate()
        hung = True
    err = err.decode("utf-8", "replace")
    rc = proc.returncode
    found = []
    if hung:
        found.append("hang")
    elif rc < 0:
        found.append("abort")
    elif rc == 101 or "panicked" in err:
        found.append("panic")
    if not hung and rc != 0:
        for p in outs:
            if p not in existed and os.path.lexists(p):
                found.append("file-left")
                break
    for p in snapshot(d):
        name = os.path.basename(p)
        if name.startswith(".") and ".tmp" in name:
            found.append("file-left")
            break
    return rc, found, err, time.time() - start


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default=os.path.join(ROOT, "target/release/vizsim"))
    ap.add_argument("--count", type=int, default=3000)
    ap.add_argument("--seed", type=int, default=17)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--timeout", type=float, default=30.0)
    ap.add_argument("--memory", type=int, default=4 << 30, help="address-space limit per run, bytes")
    ap.add_argument("--out", default=None, help="folder for the bad cases (default: a temporary folder)")
    args = ap.parse_args()
    if not os.access(args.bin, os.X_OK):
        sys.exit(f"{args.bin}: no binary; build it with cargo build --release (or give --bin)")
    out = args.out or tempfile.mkdtemp(prefix="vizsim-trial-")
    work = os.path.join(out, "cases")
    os.makedirs(work, exist_ok=True)
    rng = random.Random(args.seed)
    gen = Gen(rng)
    cases = []
    for i in range(args.count):
        d = os.path.join(work, f"c{i:05}")
        os.makedirs(d)
        kind, argv, outs = gen.case(d)
        cases.append((i, d, kind, argv, outs))
    counts = {"panic": 0, "hang": 0, "abort": 0, "file-left": 0}
    kinds, ok, clean = {}, 0, 0
    start = time.time()

    def one(case):
        i, d, kind, argv, outs = case
        return case, run_case(args.bin, d, argv, outs, args.timeout, args.memory)

    with ThreadPoolExecutor(args.jobs) as pool:
        for (i, d, kind, argv, outs), (rc, found, err, secs) in pool.map(one, cases):
            kinds[kind] = kinds.get(kind, 0) + 1
            ok += rc == 0 and not found
            clean += rc != 0 and not found
            for f in set(found):
                counts[f] += 1
            if found:
                bad = os.path.join(out, "bad", f"c{i:05}")
                os.makedirs(bad, exist_ok=True)
                with open(os.path.join(bad, "report.txt"), "w") as f:
                    f.write(f"{' '.join(found)} (exit {rc}, {secs:.1f} s)\nfolder: {d}\nvizsim {' '.join(argv)}\n\n{err[:4000]}\n")
                print(f"case {i} ({kind}): {' '.join(found)}: vizsim {' '.join(argv)}", file=sys.stderr)
            else:
                shutil.rmtree(d, ignore_errors=True)
    wall = time.time() - start
    print(f"adversarial trial: seed {args.seed}, {args.count} inputs in {wall:.0f} s "
          f"({ok} ran, {clean} refused cleanly)")
    print("inputs by kind: " + ", ".join(f"{k} {v}" for k, v in sorted(kinds.items())))
    print(f"inputs tried {args.count}, panics {counts['panic']}, hangs {counts['hang']}, "
          f"aborts {counts['abort']}, files left {counts['file-left']}")
    if any(counts.values()):
        print(f"bad cases: {os.path.join(out, 'bad')}")
        sys.exit(1)
    if not args.out:
        shutil.rmtree(out, ignore_errors=True)


if __name__ == "__main__":
    main()
