#!/usr/bin/env python3
"""Renders scripts/peers-bench.sh's JSON as a Markdown table and an SVG bar chart.

Usage: scripts/peers-report.py PEERS.json PEERS.md PEERS.svg
Every figure comes from the JSON: the emulator's yardstick (true time), its frame accounting
and the masters' own bring-up lines. Per (scenario, master) the summary table gives the median
over the runs whose master exited 0 and, in brackets, the smallest and largest of them; nothing
else is computed here but those, rounding and layout. Every run, failed ones included, also has
its own row. A file merged from several invocations (peers-bench.sh PEERS_APPEND=1) names each
invocation; a run's `label`, when present, marks its master as a variant and is shown beside it.
"""
import html
import math
import json
import statistics
import sys


def f(v, nd=1):
    if v is None:
        return "–"
    if isinstance(v, (int, float)):
        r = round(float(v), nd)
        return f"{r:.{nd}f}" if nd else f"{int(r)}"
    return str(v)


def spread(vals, nd=1, none="–"):
    """Median (min–max) of the values present; runs without one are counted."""
    have = [v for v in vals if v is not None]
    missing = len(vals) - len(have)
    if not vals:
        return "–"
    if not have:
        return none
    if len(have) == 1:
        s = f(have[0], nd)
    else:
        s = f"{f(statistics.median(have), nd)} ({f(min(have), nd)}–{f(max(have), nd)})"
    if missing:
        s += f"; {none} in {missing}"
    return s


def sync(r):
    return r.get("sync") or {}


def lock(r):
    # Lock is only meaningful where pulses were compared.
    return sync(r).get("lock_ms") if sync(r).get("pairs") else None


def emu(r):
    return r.get("emulator") or {}


def ordered(runs):
    """The runs with each scenario's together, scenarios in first-seen order and the runs of
    one scenario in their order in the file (the rounds in which they ran), so that runs
    appended by a later invocation sit after their scenario's other rows."""
    scen = {}
    for r in runs:
        scen.setdefault(r["scenario"], len(scen))
    return sorted(runs, key=lambda r: scen[r["scenario"]])


def groups(runs):
    """(scenario, master) in first-seen order, with their runs."""
    out = {}
    for r in runs:
        out.setdefault((r["scenario"], r["master"]), []).append(r)
    return out


def batch(r, data):
    """The invocation a run came from; files written before runs carried it have one."""
    return r.get("batch") or {"started": data["generated"], "command": data["command"],
                              "repeats": data.get("repeats"), "uptime_at_end": data.get("uptime_at_end")}


def name(m, rs):
    label = next((r.get("label") for r in rs if r.get("label")), None)
    return f"{m} ({label})" if label else m


def main():
    src, md_path, svg_path = sys.argv[1:4]
    with open(src) as fh:
        data = json.load(fh)
    runs = ordered(data["runs"])
    g = groups(runs)
    loads = [r.get("load_average_at_start") for r in runs if r.get("load_average_at_start") is not None]
    batches = []
    for r in runs:
        b = batch(r, data)
        if b not in batches:
            batches.append(b)
    batches.sort(key=lambda b: b["started"])
    if len(batches) == 1:
        origin = (f"Generated {batches[0]['started']} by `sudo {batches[0]['command']}` on "
                  f"{data['machine']}; ")
    else:
        origin = (f"Runs from {len(batches)} invocations on {data['machine']}: " + "; ".join(
            f"started {b['started']}, `sudo {b['command']}`" for b in batches)
            + " (the later replaced the earlier's runs of the masters it ran, nothing else); ")
    variants = sorted({r["master"] for r in runs if r.get("label")})

    lines = [
        "# Other masters on the emulator (`scripts/peers-bench.sh`)",
        "",
        origin + "each run is against a fresh `ecdc emulate` with the row's scenario file, "
        "1 ms cycle, the master and the emulator in two network namespaces joined by veth, "
        "SCHED_OTHER. Skew and lock are the emulator's true-time yardstick over the second "
        "half of the run (docs/emulator.md \"DC yardstick\"); bring-up ms is from the master's "
        "own log (ethercrab: start to all SubDevices in OP; SOEM: `ec_init` to `ec_dcsync0` "
        "done; ecdc: start to its cyclic phase); frames are what the emulator received over "
        "the whole run; dropped are frames the emulator received and did not answer, "
        "turnaround max the longest time from a frame's arrival to its reply being handed to "
        "the kernel. Each master got only the interface and the cycle"
        + (f" ({', '.join(variants)}: a labelled variant, see its command)" if variants else "")
        + ". Discussion: docs/bench.md \"Other masters\".",
        "",
        f"Host load: 1-minute load average at the start of the runs {f(min(loads), 2) if loads else '–'}"
        f"–{f(max(loads), 2) if loads else '–'}; `uptime` at the end: " + "; ".join(
            (f"{b['started']}: " if len(batches) > 1 else "")
            + f"`{(b.get('uptime_at_end') or '–').strip()}`" for b in batches) + ".",
        "",
        "## Summary: median (min–max) over the runs whose master exited 0",
        "",
        "| scenario | master | runs exit 0 | firing | mean \\|skew\\| ns | p99 ns | max ns "
        "| lock ms after 1st SYNC0 | bring-up ms | frames | dropped | turnaround max µs "
        "| AL at exit | master exits |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for (sc, m), every in g.items():
        rs = [r for r in every if r.get("exit") == 0]
        al = sorted({a for r in rs for a in (r.get("al_states") or [])})
        lines.append(
            "| " + " | ".join([
                sc, name(m, every), f"{len(rs)} of {len(every)}",
                spread([sync(r).get("slaves_firing") for r in rs], 0),
                spread([sync(r).get("skew_mean_ns") for r in rs]),
                spread([sync(r).get("skew_p99_ns") for r in rs], 0),
                spread([sync(r).get("skew_max_ns") for r in rs], 0),
                spread([lock(r) for r in rs], 1, "never"),
                spread([r.get("bring_up_ms") for r in rs], 0),
                spread([r.get("frames") for r in rs], 0),
                spread([emu(r).get("dropped") for r in rs], 0),
                spread([(emu(r).get("turnaround_ns") or {}).get("max") and
                        emu(r)["turnaround_ns"]["max"] / 1000 for r in rs], 0),
                ",".join(al) or "–",
                ",".join(str(r.get("exit")) for r in every),
            ]) + " |"
        )
    lines += ["", "Commands (binaries in `$CARGO_TARGET_DIR/release`; masters in the master "
              "namespace, the emulator in the slave namespace; the same for every run of a row):", ""]
    for (sc, m), rs in g.items():
        lines.append(f"- {sc} / {m}: `{rs[0]['command']}` against `{rs[0]['emulate_command']}`"
                     + (f" (runs started {batch(rs[0], data)['started']})" if len(batches) > 1 else ""))
    lines += [
        "",
        "## Every run",
        "",
        "| scenario | master | run | firing | pairs | mean \\|skew\\| ns | p99 ns | max ns | signed mean ns "
        "| lock ms after 1st SYNC0 | bring-up ms | frames | dropped | turnaround p99.9 / max µs "
        "| AL at exit | master exit | load |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in runs:
        s = sync(r)
        ta = emu(r).get("turnaround_ns") or {}
        us = lambda v: f(v / 1000, 0) if v is not None else "–"
        lines.append(
            "| {sc} | {m} | {run} | {fi} | {pa} | {me} | {p99} | {mx} | {sm} | {lk} | {bu} | {fr} | {dr} | {ta} | {al} | {ex} | {ld} |".format(
                sc=r["scenario"],
                m=r["master"],
                run=r.get("run", 1),
                fi=f(s.get("slaves_firing"), 0),
                pa=f(s.get("pairs"), 0),
                me=f(s.get("skew_mean_ns")),
                p99=f(s.get("skew_p99_ns"), 0),
                mx=f(s.get("skew_max_ns"), 0),
                sm=f(s.get("skew_signed_mean_ns")),
                lk=f(lock(r)) if s.get("pairs") else "–",
                bu=f(r.get("bring_up_ms"), 0),
                fr=f(r.get("frames"), 0),
                dr=f(emu(r).get("dropped"), 0),
                ta=f"{us(ta.get('p999'))} / {us(ta.get('max'))}" if ta else "–",
                al=",".join(r.get("al_states") or []),
                ex=r.get("exit"),
                ld=f(r.get("load_average_at_start"), 2),
            )
        )
    lines += ["", "Per slave clock error vs the reference in the window (signed mean / max |.|, ns):", ""]
    for r in runs:
        per = "  ".join(
            f"{p['position']}: {f(p.get('clock_error_mean_ns'))}/{f(p.get('clock_error_max_abs_ns'), 0)}"
            for p in r.get("slaves", [])
        )
        lines.append(f"- {r['scenario']} / {r['master']} #{r.get('run', 1)}: {per}")
    lines += ["", "What each master printed:", ""]
    for r in runs:
        tag = f"{r['scenario']} {r['master']} #{r.get('run', 1)}"
        for l in r.get("master_log", []):
            lines.append(f"    [{tag}] {l}")
        if "ecdc_run" in r:
            e = r["ecdc_run"]
            lines.append(
                f"    [{tag}] restarts {e.get('restarts')}, frames sent "
                f"{e.get('machine_frames_sent')}, lost {e.get('frames_lost')}, cyclic overruns "
                f"{e.get('overruns')}"
            )
    with open(md_path, "w") as fh:
        fh.write("\n".join(lines) + "\n")

    # SVG: per scenario a group of bars (one per master): the median of mean |skew| filled, its
    # min–max over the runs as a thin vertical line, the median of max |skew| as a tick.
    scen, masters = [], []
    for sc, m in g:
        if sc not in scen:
            scen.append(sc)
        if m not in masters:
            masters.append(m)
    colours = {"ethercrab": "#d95f02", "soem": "#7570b3", "ecdc": "#1b9e77", "soem-config": "#999",
               "ethercrab+ecdc": "#e7298a", "ethercrab-eeprom100": "#e6ab02"}
    vals = [sync(r).get("skew_max_ns") for r in runs]
    top = max([v for v in vals if v is not None] + [10.0])
    w, h, left, bottom, topm = 760, 340, 60, 60, 40
    plot_h = h - bottom - topm
    group_w = (w - left - 20) / max(len(scen), 1)
    bar_w = group_w / (len(masters) + 1)
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" font-family="sans-serif" font-size="12">',
           f'<rect width="{w}" height="{h}" fill="white"/>',
           f'<text x="{left}" y="16" font-size="13">SYNC0 skew in true time, {html.escape(data["generated"])}, '
           f'{"/".join(str(n) for n in sorted({len(v) for v in g.values()}))} run(s) each (log scale)</text>',
           f'<text x="{left}" y="32" font-size="11">runs whose master exited 0; bar: median mean |skew|; thin line: its min–max; '
           f'thick tick and label: median max |skew|</text>']
    # Log scale: the skews of one chart span 1 ns to tens of µs.
    decades = max(1, math.ceil(math.log10(max(top, 10.0))))

    def y(v):
        return topm + plot_h * (1 - math.log10(max(v, 1.0)) / decades)

    for k in range(decades + 1):
        v = 10 ** k
        out.append(f'<line x1="{left}" x2="{w - 20}" y1="{y(v):.1f}" y2="{y(v):.1f}" stroke="#ddd"/>')
        out.append(f'<text x="{left - 6}" y="{y(v) + 4:.1f}" text-anchor="end">{v}</text>')
    out.append(f'<text x="14" y="{topm + plot_h / 2}" transform="rotate(-90 14 {topm + plot_h / 2})" text-anchor="middle">ns (log)</text>')
    for gi, sc in enumerate(scen):
        gx = left + gi * group_w
        out.append(f'<text x="{gx + group_w / 2:.1f}" y="{h - bottom + 18}" text-anchor="middle">{html.escape(sc)}</text>')
        for mi, m in enumerate(masters):
            rs = [r for r in g.get((sc, m), []) if r.get("exit") == 0]
            means = [sync(r).get("skew_mean_ns") for r in rs if sync(r).get("skew_mean_ns") is not None]
            maxes = [sync(r).get("skew_max_ns") for r in rs if sync(r).get("skew_max_ns") is not None]
            if not means or not maxes:
                continue
            x = gx + bar_w * (mi + 0.5)
            mean, mx = statistics.median(means), statistics.median(maxes)
            c = colours.get(m, "#333")
            out.append(f'<rect x="{x:.1f}" y="{y(mean):.1f}" width="{bar_w * 0.8:.1f}" height="{y(0) - y(mean):.1f}" fill="{c}" fill-opacity="0.75"/>')
            cx = x + bar_w * 0.4
            out.append(f'<line x1="{cx:.1f}" x2="{cx:.1f}" y1="{y(min(means)):.1f}" y2="{y(max(means)):.1f}" stroke="black" stroke-width="1.5"/>')
            out.append(f'<line x1="{x:.1f}" x2="{x + bar_w * 0.8:.1f}" y1="{y(mx):.1f}" y2="{y(mx):.1f}" stroke="{c}" stroke-width="3"/>')
            out.append(f'<text x="{cx:.1f}" y="{y(mx) - 4:.1f}" text-anchor="middle" font-size="10">{mx:.0f}</text>')
    # Legend entries share the width; a variant's long name gets the room it needs.
    step = min(170, (w - left - 20) / max(len(masters), 1))
    for mi, m in enumerate(masters):
        lx = left + mi * step
        out.append(f'<rect x="{lx}" y="{h - 22}" width="12" height="12" fill="{colours.get(m, "#333")}"/>')
        out.append(f'<text x="{lx + 16}" y="{h - 12}">{html.escape(m)}</text>')
    out.append("</svg>")
    with open(svg_path, "w") as fh:
        fh.write("\n".join(out) + "\n")


if __name__ == "__main__":
    main()
