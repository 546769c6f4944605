# body_sweep_scene.py MODEL RS RATIO PLACE SHAPE [DURATION] -> a scene on stdout (the sweep of
# tests/cli_body_sweep.sh): MODEL cl (Clavet) | cy (Carreau-Yasuda, Newtonian 3.8e-4 m^2/s); a
# sphere of radius RS spacings (or a cube of side 2 RS spacings) of RATIO times the fluid's
# density, placed inside the fluid (its centre at mid-depth), half in (its centre on the
# surface) or above it (2 spacings clear), in water (970 kg/m^3) at 5 mm spacing that fills a
# tank 8 spacings wider than the body and 10 spacings plus its diameter deep, settled for
# 0.3 s (fluid.settle).
import sys
model,RS,ratio,place,shape=sys.argv[1],float(sys.argv[2]),float(sys.argv[3]),sys.argv[4],sys.argv[5]
s=0.005; R=RS*s; W=round((2*R+8*s)/s)*s; H=round((2*R+10*s)/s)*s
if model=='cy':
    fl="  model: carreau_yasuda"; eff="  carreau_yasuda: {mu0: 3.8e-4, mu_inf: 3.8e-4, n: 1}"
else:
    fl="  model: clavet_stf"; eff="  viscosity: {sigma: 2.0}\n  pressure: {k: 1000, k_near: 200}"
zc={'inside':H/2,'half':H,'above':H+R+2*s}[place]
geo=f"shape: sphere\n    radius: {R}" if shape=='sphere' else f"shape: box\n    size: [{2*R}, {2*R}, {2*R}]"
print(f"""name: sw
duration: {sys.argv[6] if len(sys.argv)>6 else 0.6}
dt: 0.001
frame_rate: 50
fluid:
{fl}
  spacing: {s}
  density: 970
  settle: 0.3
  blocks:
    - min: [{-W/2}, {-W/2}, 0.0]
      max: [{W/2}, {W/2}, {H}]
effects:
  gravity: {{g: [0, 0, -9.81]}}
{eff}
container:
  size: [{W}, {W}, {H+2*R+0.05}]
  wall: 0.01
  friction: 0.0
  stick: false
bodies:
  - name: ball
    {geo}
    density: {970*ratio}
    position: [0, 0, {zc}]
""")
