"""Forward kinematics of a URDF in plain Python (no numpy): each link's pose in the cell for
given joint values, computed independently of the web console's 3D view, to check what it draws.

Revolute, continuous and prismatic joints move about / along their axis; fixed joints do not
(mimic joints and floating joints are not supported: the robots of robots/ have none)."""
import math
import xml.etree.ElementTree as ET


def _matmul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]


def _rotation(axis, angle):
    """4x4 rotation by `angle` [rad] about the unit vector `axis` (Rodrigues)."""
    x, y, z = axis
    c, s, t = math.cos(angle), math.sin(angle), 1 - math.cos(angle)
    return [[t * x * x + c, t * x * y - s * z, t * x * z + s * y, 0],
            [t * x * y + s * z, t * y * y + c, t * y * z - s * x, 0],
            [t * x * z - s * y, t * y * z + s * x, t * z * z + c, 0],
            [0, 0, 0, 1]]


def _translation(v):
    return [[1, 0, 0, v[0]], [0, 1, 0, v[1]], [0, 0, 1, v[2]], [0, 0, 0, 1]]


def _origin(element):
    """The transform of an <origin xyz rpy> (URDF: R = Rz(yaw) Ry(pitch) Rx(roll))."""
    if element is None:
        return _translation((0, 0, 0))
    xyz = [float(v) for v in element.get("xyz", "0 0 0").split()]
    r, p, y = [float(v) for v in element.get("rpy", "0 0 0").split()]
    rot = _matmul(_rotation((0, 0, 1), y), _matmul(_rotation((0, 1, 0), p),
                                                    _rotation((1, 0, 0), r)))
    return _matmul(_translation(xyz), rot)


def base_transform(base):
    """[[robot]] base: x, y, z [m] and a rotation vector [rad]."""
    angle = math.sqrt(sum(v * v for v in base[3:]))
    rot = _rotation([v / angle for v in base[3:]], angle) if angle > 1e-12 else _translation((0, 0, 0))
    return _matmul(_translation(base[:3]), rot)


class Urdf:
    def __init__(self, text):
        root = ET.fromstring(text)
        self.links = [link.get("name") for link in root.findall("link")]
        self.joints = []
        for j in root.findall("joint"):
            axis = j.find("axis")
            a = [float(v) for v in (axis.get("xyz") if axis is not None else "1 0 0").split()]
            norm = math.sqrt(sum(v * v for v in a))
            self.joints.append({"name": j.get("name"), "type": j.get("type"),
                                "parent": j.find("parent").get("link"),
                                "child": j.find("child").get("link"),
                                "origin": _origin(j.find("origin")),
                                "axis": [v / norm for v in a]})
        children = {j["child"] for j in self.joints}
        self.root = next(link for link in self.links if link not in children)

    def link_poses(self, values, base=(0, 0, 0, 0, 0, 0)):
        """{link: 4x4 transform in the cell} for {joint name: value [rad or m]}."""
        poses = {self.root: base_transform(list(base))}
        pending = list(self.joints)
        while pending:
            ready = [j for j in pending if j["parent"] in poses]
            if not ready:
                raise ValueError("the URDF's joints do not form a tree")
            for j in ready:
                t = _matmul(poses[j["parent"]], j["origin"])
                q = values.get(j["name"], 0.0)
                if j["type"] in ("revolute", "continuous"):
                    t = _matmul(t, _rotation(j["axis"], q))
                elif j["type"] == "prismatic":
                    t = _matmul(t, _translation([a * q for a in j["axis"]]))
                poses[j["child"]] = t
                pending.remove(j)
        return poses


def quaternion_matrix(q):
    """3x3 rotation of a quaternion [x, y, z, w]."""
    x, y, z, w = q
    return [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]


def pose_error(transform, drawn):
    """Largest difference between a 4x4 transform and a drawn pose {position, quaternion}:
    (position [m], rotation matrix element [-])."""
    dp = max(abs(transform[i][3] - drawn["position"][i]) for i in range(3))
    r = quaternion_matrix(drawn["quaternion"])
    dr = max(abs(transform[i][j] - r[i][j]) for i in range(3) for j in range(3))
    return dp, dr
