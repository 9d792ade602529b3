#!/usr/bin/env python3
"""A crop of one view: the photo, the ground truth's 2D orientation and the Gabor maps', side by side.

    .venv/bin/python scripts/orient_crop.py CAPTURE ORIENT2D VIEW OUT.png Y0 Y1 X0 X1

CAPTURE a synthetic capture folder (with `gt/orientation`), ORIENT2D a `hairrecon reconstruct` output's
`orient2d/`, VIEW a view's name (e.g. view_034), the crop rows Y0:Y1 and columns X0:X1 in pixels (top
row first), each panel enlarged 3 times. Orientation as hue (θ from 0 to 180°: red, yellow, green, cyan
at 90°, i.e. along the image's columns, blue, magenta), brightness the confidence. Uses the bpy module.
"""
import sys

import bpy
import numpy as np

cap, o2d, name, out = sys.argv[1:5]
def load(p, nonc=True):
    img=bpy.data.images.load(p)
    if nonc: img.colorspace_settings.name='Non-Color'
    w,h=img.size; a=np.array(img.pixels[:],dtype=np.float32).reshape(h,w,-1)[::-1]; bpy.data.images.remove(img); return a
def hue(a):
    th=(0.5*np.arctan2(a[...,1],a[...,0]))%np.pi/np.pi
    v=np.clip(a[...,2],0,1)
    i=np.floor(th*6).astype(int)%6; f=th*6-np.floor(th*6); o=np.ones_like(th); z=np.zeros_like(th)
    r=np.choose(i,[o,1-f,z,z,f,o]); g=np.choose(i,[f,o,o,1-f,z,z]); b=np.choose(i,[z,z,f,o,o,1-f])
    return np.stack([r*v,g*v,b*v,o],-1)
ph=load(f"{cap}/images/{name}.png", nonc=False)
if ph.shape[2]==3: ph=np.concatenate([ph,np.ones(ph.shape[:2]+(1,),np.float32)],-1)
g=hue(load(f"{cap}/gt/orientation/{name}.exr")); o=hue(load(f"{o2d}/{name}.exr"))
y0,y1,x0,x1=[int(v) for v in sys.argv[5:9]]
tiles=[np.kron(a[y0:y1,x0:x1],np.ones((3,3,1),np.float32)) for a in (ph,g,o)]
pic=np.concatenate([tiles[0],np.ones((tiles[0].shape[0],6,4),np.float32),tiles[1],np.ones((tiles[0].shape[0],6,4),np.float32),tiles[2]],1)
H,W=pic.shape[:2]
im=bpy.data.images.new("c",W,H,alpha=True); im.pixels.foreach_set(np.ascontiguousarray(pic[::-1]).ravel()); im.filepath_raw=out; im.file_format='PNG'; im.save()
