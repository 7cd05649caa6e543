#!/usr/bin/python3
"""Markdown tables from the CSVs of tools/fnopt/eval.sh (written by `weft fnopt run --csv`).

    /usr/bin/python3 tools/fnopt/tables.py data/fnopt/eval
    /usr/bin/python3 tools/fnopt/tables.py data/fnopt/eval --resgrid   (the resolution table)
"""
import csv
import os
import sys

COLS = [('res', 'res'), ('motion', 'motion'), ('handles', 'handles'), ('speed', 'speed'),
        ('optimizer', 'optimizer'), ('precision', 'precision'), ('guard', 'guard'), ('max_step', 'max step'), ('iters', 'K'), ('lr', 'lr'),
        ('frames', 'frames'), ('diverged', 'diverged'), ('max_strain', 'max strain'),
        ('guard_acted', 'guard acted'), ('ms_per_frame', 'ms/frame'), ('e3d', 'e3D'),
        ('chamfer_x1e3', 'Chamfer x1e3 (m^2)')]


def table(path):
    rows = list(csv.DictReader(open(path)))
    if not rows:
        return ''
    # keep the columns that vary, plus the metrics
    # (CSVs written before the precision/guard/strain columns lack them)
    keep = [(k, h) for k, h in COLS if k in rows[0] and (k in ('ms_per_frame', 'e3d', 'chamfer_x1e3', 'diverged', 'frames')
            or len({r[k] for r in rows}) > 1)]
    out = ['| ' + ' | '.join(h for _, h in keep) + ' |', '|' + '---|' * len(keep)]
    for r in rows:
        out.append('| ' + ' | '.join(r[k] for k, _ in keep) + ' |')
    return '\n'.join(out)


def pivot_resgrid(d):
    """The resolution table of docs/FNOPT.md from resgrid.csv: one row per resolution, e3D (max
    strain) per optimizer at 10 iterations and the converged solve."""
    path = os.path.join(d, 'resgrid.csv')
    if not os.path.exists(path):
        return ''
    rows = list(csv.DictReader(open(path)))
    cols = [('learned fp32', lambda r: r['optimizer'] == 'learned' and r['precision'] == 'fp32' and r['guard'] == '1'
             and float(r['max_step']) == 0.5),
            ('learned fp32, paper rule', lambda r: r['optimizer'] == 'learned' and r['guard'] == '0'
             and float(r['max_step']) == 0),
            ('learned fp16', lambda r: r['optimizer'] == 'learned' and r['precision'] == 'fp16'),
            ('learned int8', lambda r: r['optimizer'] == 'learned' and r['precision'] == 'int8'),
            ('GD', lambda r: r['optimizer'] == 'gd'),
            ('Adam', lambda r: r['optimizer'] == 'adam'),
            ('L-BFGS', lambda r: r['optimizer'] == 'lbfgs' and r['iters'] == '10'),
            ('L-BFGS K=100 (converged)', lambda r: r['optimizer'] == 'lbfgs' and r['iters'] == '100')]
    out = ['| res | ' + ' | '.join(c for c, _ in cols) + ' |', '|---|' + '---|' * len(cols)]
    for res in sorted({int(r['res']) for r in rows}):
        cells = []
        for _, pick in cols:
            m = [r for r in rows if int(r['res']) == res and pick(r)]
            if not m:
                cells.append('')
                continue
            r = m[-1]
            if r['diverged'] == '1':
                cells.append(f"**diverged** at frame {r['frames']}")
            else:
                cells.append(f"{float(r['e3d']):.4f} ({float(r['max_strain']):.2f})")
        out.append(f'| {res} | ' + ' | '.join(cells) + ' |')
    return '\n'.join(out)


def pivot_scenes(d):
    """x2 speed and the handle placements per resolution: learned K=10 against the converged solve,
    e3D (max strain)."""
    rows = []
    for name in ('resgrid_speed.csv', 'resgrid_handles.csv'):
        path = os.path.join(d, name)
        if os.path.exists(path):
            rows += list(csv.DictReader(open(path)))
    if not rows:
        return ''
    res_list = sorted({int(r['res']) for r in rows})
    scenes = []
    for r in rows:
        key = (r['speed'], r['handles'])
        if key not in scenes:
            scenes.append(key)
    out = ['| scene | ' + ' | '.join(f'{res}: learned fp32 / int8 / converged' for res in res_list) + ' |',
           '|---|' + '---|' * len(res_list)]

    def cell(m):
        if not m:
            return '-'
        r = m[-1]
        if r['diverged'] == '1':
            return f"**diverged** ({r['frames']})"
        return f"{float(r['e3d']):.4f} ({float(r['max_strain']):.2f})"
    for speed, handles in scenes:
        label = f'x{float(speed):g} speed' if float(speed) != 1.0 else f'{handles} handles'
        cells = []
        for res in res_list:
            sel = [r for r in rows if int(r['res']) == res and r['speed'] == speed and r['handles'] == handles]
            lf = cell([r for r in sel if r['optimizer'] == 'learned' and r['precision'] == 'fp32'])
            li = cell([r for r in sel if r['optimizer'] == 'learned' and r['precision'] == 'int8'])
            cv = cell([r for r in sel if r['optimizer'] == 'lbfgs' and r['iters'] == '100'])
            cells.append(f'{lf} / {li} / {cv}')
        out.append(f'| {label} | ' + ' | '.join(cells) + ' |')
    return '\n'.join(out)


def main():
    d = sys.argv[1] if len(sys.argv) > 1 else 'data/fnopt/eval'
    for name in ['baselines', 'sweep', 'motions', 'motions_lbfgs', 'iters', 'speed', 'speed_lbfgs', 'handles',
                 'handles_lbfgs', 'res', 'res_lbfgs', 'resgrid', 'resgrid_speed', 'resgrid_handles']:
        p = os.path.join(d, name + '.csv')
        if os.path.exists(p):
            print(f'### {name}\n')
            print(table(p))
            print()


if __name__ == '__main__' and len(sys.argv) > 2 and sys.argv[2] == '--resgrid':
    print(pivot_resgrid(sys.argv[1]))
    print()
    print(pivot_scenes(sys.argv[1]))
    sys.exit(0)

if __name__ == '__main__':
    main()
