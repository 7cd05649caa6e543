#!/usr/bin/python3
"""Markdown tables from the CSVs of tools/fnopt/eval.sh (written by `weft fnopt run --csv`).

    /usr/bin/python3 tools/fnopt/tables.py data/fnopt/eval
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


def main():
    d = sys.argv[1] if len(sys.argv) > 1 else 'data/fnopt/eval'
    for name in ['baselines', 'sweep', 'motions', 'motions_lbfgs', 'iters', 'speed', 'speed_lbfgs', 'handles',
                 'handles_lbfgs', 'res', 'res_lbfgs', 'resgrid', 'resgrid_speed', 'resgrid_handles']:
        p = os.path.join(d, name + '.csv')
        if os.path.exists(p):
            print(f'### {name}\n')
            print(table(p))
            print()


if __name__ == '__main__':
    main()
