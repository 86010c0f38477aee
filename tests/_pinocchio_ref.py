"""The physics tree as a Pinocchio model: the independent reference the dynamics tests compare
against (Pinocchio is a test dependency only)."""
import numpy as np

from retime.physics.model.tree import FIXED, FREE, JOINT_DOFS, TreeModel


def to_pinocchio(tree: TreeModel, gravity=(0.0, -9.81, 0.0)):
    """The same tree as a Pinocchio model (FIXED joints become spherical joints held still).

    Returns (model, vmap): vmap[k] is Pinocchio's velocity index of our DOF k.
    """
    import pinocchio as pin

    model = pin.Model()
    model.gravity = pin.Motion(np.asarray(gravity, dtype=float), np.zeros(3))
    ids, vmap = [], []
    for j, (name, p, t) in enumerate(zip(tree.names, tree.parents, tree.jtype)):
        parent_id = 0 if p < 0 else ids[p]
        placement = pin.SE3(np.eye(3), np.zeros(3) if t == FREE else tree.offsets[j].copy())
        joint = pin.JointModelFreeFlyer() if t == FREE else pin.JointModelSpherical()
        jid = model.addJoint(parent_id, joint, placement, name)
        model.appendBodyToJoint(jid, pin.Inertia(float(tree.mass[j]), tree.com[j].copy(), tree.inertia[j].copy()),
                                pin.SE3.Identity())
        ids.append(jid)
        if t != FIXED:
            start = model.joints[jid].idx_v
            vmap += list(range(start, start + JOINT_DOFS[int(t)]))
    return model, np.array(vmap, dtype=np.int64)


def pinocchio_state(tree: TreeModel, model, root_pos, quats, qd, qdd):
    """Pinocchio (q, v, a) of one sample: root_pos (3,), quats (nb, 4), qd/qdd (nv,)."""
    q = np.zeros(model.nq)
    v = np.zeros(model.nv)
    a = np.zeros(model.nv)
    for j, t in enumerate(tree.jtype):
        jm = model.joints[j + 1]
        quat = np.asarray(quats[j], dtype=float)
        quat = quat / np.linalg.norm(quat)
        if t == FREE:
            q[jm.idx_q:jm.idx_q + 3] = root_pos
            q[jm.idx_q + 3:jm.idx_q + 7] = quat
        else:
            q[jm.idx_q:jm.idx_q + 4] = quat
        if t != FIXED:
            k = tree.vidx[j]
            dof = JOINT_DOFS[int(t)]
            v[jm.idx_v:jm.idx_v + dof] = qd[k:k + dof]
            a[jm.idx_v:jm.idx_v + dof] = qdd[k:k + dof]
    return q, v, a
