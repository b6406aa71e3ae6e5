"""Sample a mesh (OBJ) into a point cloud with normals and Gaussian noise, as `x y z nx ny nz`

Usage: python3 bench/models/sample_cloud.py MODEL.obj POINTS NOISE_FRACTION_OF_DIAGONAL OUT.xyz [SEED]

Points are spread by area over the triangles (seeded, 1 unless SEED is given, so a run is repeatable); each carries its
triangle's normal; the noise is isotropic with sigma = NOISE x the model's box diagonal.
"""
import random, math, sys, bisect
src, n, noise_frac, out = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), sys.argv[4]
V=[];F=[]
for line in open(src):
    p=line.split()
    if not p: continue
    if p[0]=='v': V.append(tuple(map(float,p[1:4])))
    elif p[0]=='f':
        idx=[int(t.split('/')[0])-1 for t in p[1:]]
        for k in range(1,len(idx)-1): F.append((idx[0],idx[k],idx[k+1]))
lo=[min(v[i] for v in V) for i in range(3)]; hi=[max(v[i] for v in V) for i in range(3)]
diag=math.dist(lo,hi); sigma=noise_frac*diag
cum=[];tot=0;normals=[]
for a,b,c in F:
    A,B,C=V[a],V[b],V[c]
    u=[B[i]-A[i] for i in range(3)]; w=[C[i]-A[i] for i in range(3)]
    nx=u[1]*w[2]-u[2]*w[1]; ny=u[2]*w[0]-u[0]*w[2]; nz=u[0]*w[1]-u[1]*w[0]
    l=math.sqrt(nx*nx+ny*ny+nz*nz); tot+=l/2; cum.append(tot)
    normals.append((nx/l,ny/l,nz/l) if l>0 else (0,0,1))
random.seed(int(sys.argv[5]) if len(sys.argv) > 5 else 1)
with open(out,'w') as f:
    for _ in range(n):
        t=bisect.bisect_left(cum,random.random()*tot); a,b,c=F[t]
        r1,r2=random.random(),random.random()
        if r1+r2>1: r1,r2=1-r1,1-r2
        A,B,C=V[a],V[b],V[c]
        p=[A[i]+r1*(B[i]-A[i])+r2*(C[i]-A[i])+random.gauss(0,sigma) for i in range(3)]
        nn=normals[t]
        f.write("%.6f %.6f %.6f %.5f %.5f %.5f\n"%(p[0],p[1],p[2],nn[0],nn[1],nn[2]))
