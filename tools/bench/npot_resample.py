#!/usr/bin/env python3
"""How much a non-power-of-two texture loses when stored at its next power-of-two sides (as atlastree's
originals are): each image is resampled in linear light, bilinearly (the old rule) and with a Catmull-Rom cubic
(`image_ops::magnify_cubic`), stored as sRGB8, then sampled bilinearly at the source's own texel centres (what
the GPU shows drawing it 1:1) and compared with the source (PSNR, dB). Needs numpy and Pillow.

    python3 tools/bench/npot_resample.py TEXTURE...
"""
import sys, numpy as np
from PIL import Image
def s2l(x): x=x/255.0; return np.where(x<=0.04045,x/12.92,((x+0.055)/1.055)**2.4)
def l2s(x): x=np.clip(x,0,1); return np.round(255*np.where(x<=0.0031308,12.92*x,1.055*x**(1/2.4)-0.055))
def taps_lin(src,out):
    pos=(np.arange(out)+0.5)*src/out-0.5; i=np.floor(pos).astype(int); t=pos-i
    return [(np.mod(i,src),1-t),(np.mod(i+1,src),t)]
def taps_cub(src,out):
    pos=(np.arange(out)+0.5)*src/out-0.5; i=np.floor(pos).astype(int); t=pos-i
    w=[0.5*(-t**3+2*t**2-t),0.5*(3*t**3-5*t**2+2),0.5*(-3*t**3+4*t**2+t),0.5*(t**3-t**2)]
    return [(np.mod(i+k-1,src),w[k]) for k in range(4)]
def res(img,W,H,taps):
    h,w,_=img.shape
    a=sum(img[:,ix,:]*wt[None,:,None] for ix,wt in taps(w,W))
    b=sum(a[iy,:,:]*wt[:,None,None] for iy,wt in taps(h,H))
    return b
def p2(v): return 1<<(v-1).bit_length()
def psnr(a,b): m=np.mean((a-b)**2); return 99 if m==0 else 10*np.log10(255**2/m)
for f in sys.argv[1:]:
    im=np.asarray(Image.open(f).convert('RGB')).astype(float)
    h,w,_=im.shape; W,H=min(p2(w),2048),min(p2(h),2048)
    lin=s2l(im)
    out=[]
    for name,t in (('bilinear',taps_lin),('cubic',taps_cub)):
        st=np.clip(res(lin,W,H,t),0,1)
        st=s2l(l2s(st))  # stored as sRGB8
        back=res(st,w,h,taps_lin)  # GPU bilinear at source texel centres
        out.append(psnr(l2s(back),im))
    print(f"{f.split('/')[-1]:40s} {w}x{h}->{W}x{H}: bilinear {out[0]:.2f} dB, cubic {out[1]:.2f} dB")
