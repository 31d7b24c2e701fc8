"""plugflow's side of YADE: one scene built from the JSON the Rust shim writes (see
input.rs), stepped, read and written in bulk so that each coupling exchange crosses the
Python boundary a handful of times, not once per grain and quantity."""

import contextlib
import io
import json
import math
import os
import sys

_scene = None


def boot(threads, path):
    """Import YADE once per process: OpenMP reads OMP_NUM_THREADS when YADE loads, and
    `import yade` prints a banner we keep off the host's stdout. The scene's `dem.threads`
    wins over an inherited OMP_NUM_THREADS: the scene says how many cores the run may use."""
    os.environ["OMP_NUM_THREADS"] = str(threads)
    if path not in sys.path:
        sys.path.insert(0, path)
    banner = io.StringIO()
    with contextlib.redirect_stdout(banner):
        import yade  # noqa: F401
        import yade.config
    return str(yade.config.version)


class Scene:
    def __init__(self, setup):
        import yade
        from yade import O, utils
        from yade import wrapper as w

        self.O = O
        self.w = w
        self.V = yade.Vector3
        O.reset()
        s = json.loads(setup)
        self.s = s
        O.dt = s["dt"]
        law = s["law"]
        if law == "viscel":
            mat = lambda m: w.ViscElMat(
                kn=m["kn"], ks=m["ks"], cn=m["cn"], cs=m["cs"],
                frictionAngle=m["friction_angle"], density=m["density"])
            ip2 = w.Ip2_ViscElMat_ViscElMat_ViscElPhys()
            law2 = w.Law2_ScGeom_ViscElPhys_Basic()
        elif law == "mindlin":
            mat = lambda m: w.FrictMat(
                young=m["young"], poisson=m["poisson"],
                frictionAngle=m["friction_angle"], density=m["density"])
            ip2 = None
            law2 = w.Law2_ScGeom_MindlinPhys_Mindlin()
        else:
            raise ValueError("unknown law " + law)
        self.grain_mat = O.materials.append(mat(s["grain"]))
        cap_mat = O.materials.append(mat(s["cap"]))
        tube_mat = O.materials.append(mat(s["tube_wall"]))
        if law == "mindlin":
            g = self.grain_mat
            en = w.MatchMaker(
                matches=((g, g, s["en_pp"]), (g, cap_mat, s["en_pw"]), (g, tube_mat, s["en_pw"])),
                algo="val", val=s["en_pp"])
            ip2 = w.Ip2_FrictMat_FrictMat_MindlinPhys(en=en, es=en)
        # Walls: groups of body ids, reported by name.
        self.walls = []
        for c in s["caps"]:
            b = utils.wall(c["position"], axis=c["axis"], sense=0, material=cap_mat)
            self.walls.append((c["name"], [O.bodies.append(b)]))
        t = s["tube"]
        if t is not None:
            # The tube as a regular polygon of long thin boxes, the inner face of box k
            # spanning the angles 2πk/N..2π(k+1)/N. Boxes, not facets: YADE's facet
            # contacts count a grain twice where it straddles two coplanar triangles.
            rot = {0: yade.Quaternion((0, 1, 0), math.pi / 2),
                   1: yade.Quaternion((1, 0, 0), -math.pi / 2),
                   2: yade.Quaternion((1, 0, 0), 0.0)}[t["axis"]]
            n = t["segments"]
            half = math.pi / n
            apothem = t["vertex_radius"] * math.cos(half)
            side = 2.0 * t["vertex_radius"] * math.sin(half)
            thick = t["thickness"]
            length = t["end"] - t["start"]
            mid = 0.5 * (t["start"] + t["end"])
            centre = yade.Vector3(*t["centre"])
            centre[t["axis"]] = 0.0
            ids = []
            for k in range(n):
                phi = (2 * k + 1) * half
                local = yade.Vector3((apothem + thick) * math.cos(phi),
                                     (apothem + thick) * math.sin(phi), 0.0)
                pos = centre + rot * local
                pos[t["axis"]] = mid
                ori = rot * yade.Quaternion((0, 0, 1), phi)
                b = utils.box(pos, (thick, 0.5 * side, 0.5 * length), orientation=ori,
                              fixed=True, material=tube_mat)
                ids.append(O.bodies.append(b))
            self.walls.append((t["name"], ids))
        O.engines = [
            w.ForceResetter(),
            w.InsertionSortCollider(
                [w.Bo1_Sphere_Aabb(), w.Bo1_Box_Aabb(), w.Bo1_Wall_Aabb()],
                verletDist=s["skin"]),
            w.InteractionLoop(
                [w.Ig2_Sphere_Sphere_ScGeom(), w.Ig2_Box_Sphere_ScGeom(),
                 w.Ig2_Wall_Sphere_ScGeom()],
                [ip2], [law2]),
            w.NewtonIntegrator(gravity=s["gravity"], damping=0.0),
        ]
        self.utils = utils
        # plugflow ids never repeat within a run; YADE reuses freed body ids.
        self.pf_id = {}
        self.next_id = 0
        self.order = []

    def step(self, n):
        step = self.O.step
        for _ in range(n):
            step()

    def state(self):
        """id, x, v, ω, r, m of every grain, flat, in body order; remembers the order for
        set_forces."""
        out = []
        order = []
        bodies = self.O.bodies
        pf = self.pf_id
        for bid in sorted(pf):
            b = bodies[bid]
            st = b.state
            p, v, a = st.pos, st.vel, st.angVel
            out.extend((float(pf[bid]), p[0], p[1], p[2], v[0], v[1], v[2],
                        a[0], a[1], a[2], b.shape.radius, st.mass))
            order.append(bid)
        self.order = order
        return out

    def set_forces(self, f):
        """Per-grain fluid forces (flat x, y, z) in the order of the last state(); YADE
        applies a permanent force at every step until it is set again."""
        setF = self.O.forces.setPermF
        V = self.V
        for i, bid in enumerate(self.order):
            setF(bid, V(f[3 * i], f[3 * i + 1], f[3 * i + 2]))

    def insert(self, g):
        """Grains (flat x, y, z, vx, vy, vz, r, ρ); returns their plugflow ids."""
        ids = []
        sphere = self.utils.sphere
        no_rotation = not self.s["rotation"]
        for k in range(0, len(g), 8):
            x, y, z, vx, vy, vz, r, rho = g[k:k + 8]
            b = sphere((x, y, z), r, material=self.grain_mat)
            b.state.mass = rho * 4.0 / 3.0 * math.pi * r ** 3
            b.state.inertia = self.V(*([0.4 * b.state.mass * r * r] * 3))
            b.state.vel = self.V(vx, vy, vz)
            if no_rotation:
                b.state.blockedDOFs = "XYZ"
            bid = self.O.bodies.append(b)
            self.pf_id[bid] = self.next_id
            ids.append(self.next_id)
            self.next_id += 1
        # Grow the force container to the new bodies now (it does so only when stepping),
        # so setPermF on them is valid; permanent forces are kept.
        self.O.forces.reset(False)
        return ids

    def _bodies_of(self, pf_ids):
        want = set(pf_ids)
        return [b for b, p in self.pf_id.items() if p in want]

    def hold(self, pf_ids, v):
        """Hold grains to the conveyor's feed motion: every degree of freedom blocked (YADE
        then moves them at their velocity, deaf to forces and gravity), velocity v, no spin."""
        if not pf_ids:
            return
        bodies = self.O.bodies
        vel = self.V(*v)
        zero = self.V(0.0, 0.0, 0.0)
        for bid in self._bodies_of(pf_ids):
            st = bodies[bid].state
            st.blockedDOFs = "xyzXYZ"
            st.vel = vel
            st.angVel = zero

    def release(self, pf_ids):
        """Let held grains go: they answer forces again from their current velocity."""
        if not pf_ids:
            return
        bodies = self.O.bodies
        free = "XYZ" if not self.s["rotation"] else ""
        for bid in self._bodies_of(pf_ids):
            bodies[bid].state.blockedDOFs = free

    def remove(self, pf_ids):
        """Erase grains by plugflow id."""
        gone = set(pf_ids)
        for bid in [b for b, p in self.pf_id.items() if p in gone]:
            self.O.bodies.erase(bid)
            del self.pf_id[bid]

    def wall_forces(self):
        """Force on each wall group (x, y, z), flat, in the order of `walls`."""
        out = []
        f = self.O.forces.f
        for _, ids in self.walls:
            s = [0.0, 0.0, 0.0]
            for i in ids:
                v = f(i)
                s[0] += v[0]
                s[1] += v[1]
                s[2] += v[2]
            out.extend(s)
        return out

    def wall_names(self):
        return [n for n, _ in self.walls]


def create(setup):
    global _scene
    _scene = Scene(setup)
    return _scene


def destroy():
    global _scene
    if _scene is not None:
        _scene.O.reset()
    _scene = None
