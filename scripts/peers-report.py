#!/usr/bin/env python3
"""Renders scripts/peers-bench.sh's JSON as a Markdown table and an SVG bar chart.

Usage: scripts/peers-report.py PEERS.json PEERS.md PEERS.svg
Every figure comes from the JSON: the emulator's yardstick (true time) and the masters' own
bring-up lines; nothing is computed here but rounding and layout.
"""
import html
import math
import json
import sys


def f(v, nd=1):
    if v is None:
        return "–"
    if isinstance(v, (int, float)):
        r = round(float(v), nd)
        return f"{r:.{nd}f}" if nd else f"{int(r)}"
    return str(v)


def main():
    src, md_path, svg_path = sys.argv[1:4]
    with open(src) as fh:
        data = json.load(fh)
    runs = data["runs"]

    lines = [
        "# Other masters on the emulator (`scripts/peers-bench.sh`)",
        "",
        f"Generated {data['generated']} by `sudo {data['command']}` on {data['machine']}; "
        "each row is one run against a fresh `ecdc emulate` with the row's scenario file, "
        "1 ms cycle, the master and the emulator in two network namespaces joined by veth, "
        "SCHED_OTHER. Skew and lock are the emulator's true-time yardstick over the second "
        "half of the run (docs/emulator.md \"DC yardstick\"); bring-up ms is from the master's "
        "own log (ethercrab: start to all SubDevices in OP; SOEM: `ec_init` to `ec_dcsync0` "
        "done; ecdc: start to its cyclic phase); frames are what the emulator received over "
        "the whole run. Each master got only the interface and the cycle. The load average "
        "is the host's 1-minute load when the run started. Discussion: docs/bench.md "
        "\"Other masters\".",
        "",
        "| scenario | master | firing | pairs | mean \\|skew\\| ns | p99 ns | max ns | signed mean ns "
        "| lock ms after 1st SYNC0 | bring-up ms | frames | AL at exit | master exit | load |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in runs:
        s = r["sync"] or {}
        lines.append(
            "| {sc} | {m} | {fi} | {pa} | {me} | {p99} | {mx} | {sm} | {lk} | {bu} | {fr} | {al} | {ex} | {ld} |".format(
                sc=r["scenario"],
                m=r["master"],
                fi=f(s.get("slaves_firing"), 0),
                pa=f(s.get("pairs"), 0),
                me=f(s.get("skew_mean_ns")),
                p99=f(s.get("skew_p99_ns"), 0),
                mx=f(s.get("skew_max_ns"), 0),
                sm=f(s.get("skew_signed_mean_ns")),
                lk=f(s.get("lock_ms")) if s.get("pairs") else "–",
                bu=f(r.get("bring_up_ms"), 0),
                fr=f(r.get("frames"), 0),
                al=",".join(r.get("al_states") or []),
                ex=r.get("exit"),
                ld=f(r.get("load_average_at_start"), 2),
            )
        )
    lines += ["", "Commands (binaries in `$CARGO_TARGET_DIR/release`; masters in the master "
              "namespace, the emulator in the slave namespace):", ""]
    for r in runs:
        lines.append(f"- {r['scenario']} / {r['master']}: `{r['command']}` against "
                     f"`{r['emulate_command']}`")
    lines += ["", "Per slave clock error vs the reference in the window (signed mean / max |.|, ns):", ""]
    for r in runs:
        per = "  ".join(
            f"{p['position']}: {f(p.get('clock_error_mean_ns'))}/{f(p.get('clock_error_max_abs_ns'), 0)}"
            for p in r.get("slaves", [])
        )
        lines.append(f"- {r['scenario']} / {r['master']}: {per}")
    lines += ["", "What each master printed:", ""]
    for r in runs:
        for l in r.get("master_log", []):
            lines.append(f"    [{r['scenario']} {r['master']}] {l}")
        if "ecdc_run" in r:
            e = r["ecdc_run"]
            lines.append(
                f"    [{r['scenario']} ecdc] restarts {e.get('restarts')}, frames sent "
                f"{e.get('machine_frames_sent')}, lost {e.get('frames_lost')}, cyclic overruns "
                f"{e.get('overruns')}"
            )
    with open(md_path, "w") as fh:
        fh.write("\n".join(lines) + "\n")

    # SVG: per scenario a group of bars (one per master): mean |skew| filled, max as a tick.
    scen = []
    for r in runs:
        if r["scenario"] not in scen:
            scen.append(r["scenario"])
    masters = []
    for r in runs:
        if r["master"] not in masters:
            masters.append(r["master"])
    colours = {"ethercrab": "#d95f02", "soem": "#7570b3", "ecdc": "#1b9e77", "soem-config": "#999"}
    vals = [v for r in runs for v in ((r["sync"] or {}).get("skew_max_ns"),) if v is not None]
    top = max(vals + [10.0])
    w, h, left, bottom, topm = 760, 340, 60, 60, 40
    plot_h = h - bottom - topm
    group_w = (w - left - 20) / max(len(scen), 1)
    bar_w = group_w / (len(masters) + 1)
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" font-family="sans-serif" font-size="12">',
           f'<rect width="{w}" height="{h}" fill="white"/>',
           f'<text x="{left}" y="20" font-size="14">SYNC0 skew in true time (bar: mean |skew|, line: max; log scale), '
           f'{html.escape(data["generated"])}</text>']
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
            r = next((r for r in runs if r["scenario"] == sc and r["master"] == m), None)
            if r is None or not r["sync"] or r["sync"].get("skew_mean_ns") is None:
                continue
            x = gx + bar_w * (mi + 0.5)
            mean, mx = r["sync"]["skew_mean_ns"], r["sync"]["skew_max_ns"]
            c = colours.get(m, "#333")
            out.append(f'<rect x="{x:.1f}" y="{y(mean):.1f}" width="{bar_w * 0.8:.1f}" height="{y(0) - y(mean):.1f}" fill="{c}"/>')
            out.append(f'<line x1="{x:.1f}" x2="{x + bar_w * 0.8:.1f}" y1="{y(mx):.1f}" y2="{y(mx):.1f}" stroke="{c}" stroke-width="3"/>')
            out.append(f'<text x="{x + bar_w * 0.4:.1f}" y="{y(mx) - 4:.1f}" text-anchor="middle" font-size="10">{mx:.0f}</text>')
    for mi, m in enumerate(masters):
        lx = left + mi * 110
        out.append(f'<rect x="{lx}" y="{h - 22}" width="12" height="12" fill="{colours.get(m, "#333")}"/>')
        out.append(f'<text x="{lx + 16}" y="{h - 12}">{html.escape(m)}</text>')
    out.append("</svg>")
    with open(svg_path, "w") as fh:
        fh.write("\n".join(out) + "\n")


if __name__ == "__main__":
    main()
