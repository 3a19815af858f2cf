#!/usr/bin/env python3
"""Circles between the files of each crate: every file's `crate::`, `super::` and `self::`
paths (comments and `#[cfg(test)] mod tests` left out) point at the file module they name;
a path to one of a file's own ancestor modules does not count (a submodule is part of its
parent). Prints each strongly connected component of more than one file, nothing when
there is none, and exits 1 when there is one.

    python3 scripts/module_cycles.py config/src estimator/src sim/src hwio/src serve/src src python/src
"""
import os
import re
import sys

# file-level import graph per crate: module path -> file; edges from `use crate::a::b`, `use super::x`, `crate::a::b::` paths in code
def modpath(root,f):
    rel=os.path.relpath(f,root)[:-3].split('/')
    if rel[-1] in('mod','lib','main'): rel=rel[:-1]
    return tuple(rel)
def scan(crate_src):
    files={}
    for d,_,fs in os.walk(crate_src):
        for f in fs:
            if f.endswith('.rs'): files[modpath(crate_src,os.path.join(d,f))]=os.path.join(d,f)
    edges={m:set() for m in files}
    for m,f in files.items():
        src=open(f).read()
        # the tests' own module is not part of the product's layering
        src=re.split(r'#\[cfg\(test\)\]\s*mod tests',src)[0]
        src=re.sub(r'//[^\n]*','',src)
        here=m
        for path in re.findall(r'\b((?:crate|super|self)(?:::\w+)+)',src):
            parts=path.split('::')
            if parts[0]=='crate': base=(); rest=parts[1:]
            elif parts[0]=='self': base=here; rest=parts[1:]
            else:
                base=here; rest=parts
                while rest and rest[0]=='super': base=base[:-1]; rest=rest[1:]
            # longest prefix that is a file module
            tgt=None
            for k in range(len(rest),-1,-1):
                cand=base+tuple(rest[:k])
                if cand in files: tgt=cand; break
            if tgt is not None and tgt!=m and not (len(tgt)<len(m) and m[:len(tgt)]==tgt):
                edges[m].add(tgt)
    return files,edges
def sccs(edges):
    idx={};low={};st=[];on=set();out=[];c=[0]
    sys.setrecursionlimit(10000)
    def sc(v):
        idx[v]=low[v]=c[0];c[0]+=1;st.append(v);on.add(v)
        for w in edges[v]:
            if w not in idx: sc(w);low[v]=min(low[v],low[w])
            elif w in on: low[v]=min(low[v],idx[w])
        if low[v]==idx[v]:
            comp=[]
            while True:
                w=st.pop();on.discard(w);comp.append(w)
                if w==v:break
            if len(comp)>1: out.append(comp)
    for v in edges:
        if v not in idx: sc(v)
    return out
found = False
for crate in sys.argv[1:]:
    files, edges = scan(crate)
    for comp in sccs(edges):
        found = True
        print(crate, ' <-> '.join('::'.join(x) or 'lib' for x in sorted(comp)))
sys.exit(1 if found else 0)
