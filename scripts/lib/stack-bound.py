#!/usr/bin/env python3
"""Static worst-case stack of a call tree in a Cortex-M ELF, from its disassembly.

    stack-bound.py OBJDUMP ELF ROOT_SUBSTRING [ROOT_SUBSTRING...]
    stack-bound.py OBJDUMP ELF --entry MAIN --task POLL [--task POLL ...] [--isr HANDLER ...]
                   [--once FUNC ...]

`--path` (either form) also prints, indented, the call chain that gives each root its bound
(frame and bound of every function on it): where to look when a bound grows.

The second form also prints each task's worst case on the main stack (embassy's thread-mode
executor polls every task on it, one at a time): the entry's bound (main and the executor loop)
+ the task's poll + for each interrupt handler its bound and an exception frame with the FPU
context (104 B), as if every handler nested once. The stack's worst case is the largest.
`--once FUNC` (the function's whole name): a function the entry calls before the executor
polls any task (boot, run as the executor's `init`): left out of the entry's bound and
counted like a task instead.

For every function: its frame is the sum of every `push`/`stmdb sp!`/`vpush` and
`sub sp, #N` it contains (an upper bound: a path runs each at most once, and a function that
pushes on two alternative paths is counted twice). Its callees are the targets of `bl` and of
`b`/`b.w` to the start of another function (tail calls, counted as if nested: an upper bound).
The bound of a root is its frame plus the largest bound of its callees, found depth first.

Limits, printed with the result: indirect calls (`blx rN`: trait objects, function pointers,
fmt::Write) are not followed, a call cycle (recursion) stops the walk and is reported, and the
frames of interrupt handlers that may nest on top are not included (pass their names as roots
to see them). Used by scripts/fw-build for every task (the RAM budget); docs/qemu.md
compares it with the stack painting measured under QEMU.
"""

import re
import subprocess
import sys

FUNC = re.compile(r"^([0-9a-f]+) <(.*)>:$")
INSN = re.compile(r"^\s*([0-9a-f]+):\s+(\S+)\s*(.*)$")
TARGET = re.compile(r"^([0-9a-f]+) <(.*)>$")


def regs(text):
    """Number of registers in a {r4, r5-r7, lr} list."""
    inside = text[text.find("{") + 1 : text.find("}")]
    n = 0
    for part in inside.split(","):
        part = part.strip()
        if "-" in part:
            a, b = part.split("-")
            n += int(re.sub(r"\D", "", b)) - int(re.sub(r"\D", "", a)) + 1
        elif part:
            n += 1
    return n


def parse(objdump, elf):
    out = subprocess.run(
        [objdump, "-d", "--no-show-raw-insn", "-C", elf],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    funcs = {}  # start address -> dict(name, frame, calls, indirect)
    cur = None
    for line in out.splitlines():
        m = FUNC.match(line)
        if m:
            cur = {"name": m.group(2), "frame": 0, "calls": set(), "indirect": 0}
            funcs[int(m.group(1), 16)] = cur
            continue
        m = INSN.match(line)
        if not m or cur is None:
            continue
        op, args = m.group(2), m.group(3)
        if op in ("push", "push.w") or (op.startswith("stmdb") and args.startswith("sp!")):
            cur["frame"] += 4 * regs(args)
        elif op.startswith("vpush"):
            per = 8 if "d" in args.split("{")[1][:2] else 4
            cur["frame"] += per * regs(args)
        elif op in ("sub", "sub.w", "subw", "sub.n") and args.startswith("sp, "):
            imm = re.search(r"#(\d+)", args)
            if imm:
                cur["frame"] += int(imm.group(1))
        elif op in ("bl", "b", "b.w", "b.n") or op.startswith("b."):
            t = TARGET.match(args)
            if t and "+0x" not in t.group(2):
                cur["calls"].add(int(t.group(1), 16))
            elif op == "bl" and t:
                cur["calls"].add(int(t.group(1), 16))
        elif op.startswith("blx"):
            cur["indirect"] += 1
    return funcs


def bound(funcs, addr, memo, stack, notes, skip=frozenset()):
    if addr in memo:
        return memo[addr]
    f = funcs.get(addr)
    if f is None:
        return 0
    if addr in stack:
        notes.add("recursion through " + f["name"][:80])
        return 0
    stack.add(addr)
    if f["indirect"]:
        notes.add(f"{f['indirect']} indirect call(s) in {f['name'][:80]}")
    deepest = 0
    for c in f["calls"]:
        if c != addr and c not in skip:
            deepest = max(deepest, bound(funcs, c, memo, stack, notes, skip))
    stack.discard(addr)
    memo[addr] = f["frame"] + deepest
    return memo[addr]


def worst_path(funcs, addr, memo):
    """The call chain that gives `addr` its bound (after `bound` filled `memo`)."""
    path, seen = [], set()
    while addr in funcs and addr not in seen:
        seen.add(addr)
        f = funcs[addr]
        path.append((f["frame"], memo.get(addr, f["frame"]), f["name"]))
        callees = [c for c in f["calls"] if c != addr and c in memo and c not in seen]
        if not callees:
            break
        addr = max(callees, key=lambda c: memo[c])
    return path


def report(funcs, root, show_path=False, skip=frozenset(), exact=False):
    """Bound of every function whose name contains `root` (is `root`, if `exact`; printed);
    the largest, or None. Calls into `skip` (addresses) are not followed."""
    hits = [a for a, f in funcs.items() if (root == f["name"] if exact else root in f["name"])]
    if not hits:
        print(f"stack bound: no function matches '{root}'")
        return None
    best = 0
    for a in hits:
        notes = set()
        memo = {}
        b = bound(funcs, a, memo, set(), notes, skip)
        best = max(best, b)
        print(f"stack bound {b} B: {funcs[a]['name'][:110]}")
        if show_path:
            for frame, total, name in worst_path(funcs, a, memo):
                print(f"    frame {frame:5} B, bound {total:5} B: {name[:120]}")
        for n in sorted(notes)[:8]:
            print(f"    not followed: {n}")
        if len(notes) > 8:
            print(f"    ... and {len(notes) - 8} more")
    return best


EXCEPTION_FRAME_FPU = 104  # 8 core + 18 FPU words stacked on entry (lazy stacking reserves them)


def main():
    args = sys.argv[1:]
    if len(args) < 3:
        print(__doc__, file=sys.stderr)
        return 2
    objdump, elf, rest = args[0], args[1], args[2:]
    show_path = "--path" in rest
    rest = [r for r in rest if r != "--path"]
    funcs = parse(objdump, elf)
    if "--task" not in rest:
        return 0 if all(report(funcs, r, show_path) is not None for r in rest) else 1
    entry, tasks, isrs, once = None, [], [], []
    it = iter(rest)
    for flag in it:
        value = next(it, None)
        if flag == "--entry":
            entry = value
        elif flag == "--task":
            tasks.append(value)
        elif flag == "--isr":
            isrs.append(value)
        elif flag == "--once":
            once.append(value)
    skip = frozenset(a for a, f in funcs.items() if f["name"] in once)
    base = [report(funcs, r, show_path, skip) for r in [entry] + isrs if r is not None]
    polls = [(t, report(funcs, t, show_path)) for t in tasks]
    polls += [(o, report(funcs, o, show_path, exact=True)) for o in once]
    if any(p is None for p in base) or any(b is None for _, b in polls):
        return 1
    extra = sum(base) + EXCEPTION_FRAME_FPU * len(isrs)
    for t, b in polls:
        print(
            f"stack bound worst case with {t[:40]}: {extra + b} B "
            f"(entry + task + {len(isrs)} nested handler(s) with FPU frames)"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
