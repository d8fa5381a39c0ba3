#!/usr/bin/env python3
"""Longest Rust functions under a directory: `python3 tools/longest_fns.py src 10`.
Length = lines from the `fn` line to its matching closing brace (inclusive).
Strings, chars and comments are skipped when matching braces; #[cfg(test)] code counts like any other."""
import re, sys, os
if not 2 <= len(sys.argv) <= 3 or not os.path.isdir(sys.argv[1]) or (len(sys.argv) == 3 and not sys.argv[2].isdigit()):
    sys.exit("usage: tools/longest_fns.py DIR [N]   (DIR: a folder of Rust sources; N: how many, default 10)")
root = sys.argv[1]; n = int(sys.argv[2]) if len(sys.argv) > 2 else 10
fn_re = re.compile(r'^\s*(pub(\([^)]*\))?\s+)?(const\s+)?(async\s+)?(unsafe\s+)?(extern\s+"[^"]*"\s+)?fn\s+(\w+)')
def strip(line, state):
    # remove strings/comments; state carries block comment depth
    out = []; i = 0
    while i < len(line):
        if state['bc']:
            if line.startswith('*/', i): state['bc'] -= 1; i += 2
            elif line.startswith('/*', i): state['bc'] += 1; i += 2
            else: i += 1
            continue
        if state['str']:
            if line[i] == '\\': i += 2; continue
            if line[i] == '"': state['str'] = False
            i += 1; continue
        c = line[i]
        if line.startswith('//', i): break
        if line.startswith('/*', i): state['bc'] += 1; i += 2; continue
        if c == '"': state['str'] = True; i += 1; continue
        if c == "'" and re.match(r"'(\\.|[^\\'])'", line[i:]):
            i += len(re.match(r"'(\\.|[^\\'])'", line[i:]).group(0)); continue
        out.append(c); i += 1
    return ''.join(out)
res = []
for d, _, fs in os.walk(root):
    for f in fs:
        if not f.endswith('.rs'): continue
        p = os.path.join(d, f); lines = open(p).read().split('\n')
        state = {'bc': 0, 'str': False}
        code = [strip(l, state) for l in lines]
        for i, l in enumerate(lines):
            m = fn_re.match(code[i])
            if not m: continue
            depth = 0; started = False
            for j in range(i, len(lines)):
                for ch in code[j]:
                    if ch == '{': depth += 1; started = True
                    elif ch == '}': depth -= 1
                    elif ch == ';' and not started and depth == 0: break
                if started and depth == 0:
                    res.append((j - i + 1, f'{p}:{i+1}', m.group(7))); break
                if not started and ';' in code[j] and depth == 0: break
res.sort(key=lambda r: -r[0])
for r in res[:n]: print(f'{r[0]:5d}  {r[2]:28s} {r[1]}')
