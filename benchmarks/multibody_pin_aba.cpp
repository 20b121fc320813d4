// Pinocchio's ABA in a C++ loop, for benchmarks/multibody.py and benchmarks/generalized_speeds.py:
// reads a tree (one joint per line: parent kind ax ay az  R00..R22  tx ty tz  mass cx cy cz  Ixx Ixy
// Ixz Iyy Iyz Izz; kind 0 revolute and 1 prismatic about the unaligned axis a, 2-4 revolute about x,
// y, z, 5-7 prismatic along x, y, z, 8 free flyer (a ignored); Pinocchio's own joint kinds, so that
// its aligned joints keep their cheaper code) from argv[1], the states (nq values of q, then nv of
// v, each) from argv[2], and prints the nanoseconds per aba call over argv[3] seconds, then the
// accelerations of the first state.
#include <pinocchio/multibody.hpp>
#include <pinocchio/algorithm/aba.hpp>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <vector>

int main(int argc, char **argv)
{
    if (argc < 4) return 2;
    pinocchio::Model model;
    model.gravity.linear(Eigen::Vector3d(0, 0, -9.81));
    std::ifstream in(argv[1]);
    int parent, kind;
    std::vector<pinocchio::JointIndex> ids;
    while (in >> parent >> kind) {
        double a[3], R[9], t[3], m, c[3], I[6];
        for (double &x : a) in >> x;
        for (double &x : R) in >> x;
        for (double &x : t) in >> x;
        in >> m;
        for (double &x : c) in >> x;
        for (double &x : I) in >> x;
        Eigen::Matrix3d Rm;
        Rm << R[0], R[1], R[2], R[3], R[4], R[5], R[6], R[7], R[8];
        pinocchio::SE3 X(Rm, Eigen::Vector3d(t[0], t[1], t[2]));
        Eigen::Vector3d axis(a[0], a[1], a[2]);
        pinocchio::JointIndex pid = parent < 0 ? 0 : ids[parent];
        const std::string name = "j" + std::to_string(ids.size());
        pinocchio::JointIndex id;
        switch (kind) {
        case 0: id = model.addJoint(pid, pinocchio::JointModelRevoluteUnaligned(axis), X, name); break;
        case 1: id = model.addJoint(pid, pinocchio::JointModelPrismaticUnaligned(axis), X, name); break;
        case 2: id = model.addJoint(pid, pinocchio::JointModelRX(), X, name); break;
        case 3: id = model.addJoint(pid, pinocchio::JointModelRY(), X, name); break;
        case 4: id = model.addJoint(pid, pinocchio::JointModelRZ(), X, name); break;
        case 5: id = model.addJoint(pid, pinocchio::JointModelPX(), X, name); break;
        case 6: id = model.addJoint(pid, pinocchio::JointModelPY(), X, name); break;
        case 7: id = model.addJoint(pid, pinocchio::JointModelPZ(), X, name); break;
        case 8: id = model.addJoint(pid, pinocchio::JointModelFreeFlyer(), X, name); break;
        default: return 4;
        }
        Eigen::Matrix3d Im;
        Im << I[0], I[1], I[2], I[1], I[3], I[4], I[2], I[4], I[5];
        model.appendBodyToJoint(id, pinocchio::Inertia(m, Eigen::Vector3d(c[0], c[1], c[2]), Im), pinocchio::SE3::Identity());
        ids.push_back(id);
    }
    pinocchio::Data data(model);
    const int n = model.nv, nq = model.nq;
    std::ifstream sin(argv[2]);
    std::vector<Eigen::VectorXd> qs, vs;
    while (true) {
        Eigen::VectorXd q(nq), v(n);
        for (int i = 0; i < nq; ++i) if (!(sin >> q[i])) goto done;
        for (int i = 0; i < n; ++i) if (!(sin >> v[i])) goto done;
        qs.push_back(q);
        vs.push_back(v);
    }
done:
    if (qs.empty()) return 3;
    Eigen::VectorXd tau = Eigen::VectorXd::Zero(n);
    double target = std::atof(argv[3]), sink = 0;
    long calls = 64;
    for (;;) {
        auto t0 = std::chrono::steady_clock::now();
        for (long k = 0; k < calls; ++k) {
            pinocchio::aba(model, data, qs[k % qs.size()], vs[k % vs.size()], tau);
            sink += data.ddq[n - 1];
        }
        double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        if (s > target) {
            std::printf("%.6e %g\n", 1e9 * s / (double)calls, sink * 0);
            break;
        }
        calls *= 2;
    }
    pinocchio::aba(model, data, qs[0], vs[0], tau);
    for (int i = 0; i < n; ++i) std::printf("%.17g\n", data.ddq[i]);
    return 0;
}
