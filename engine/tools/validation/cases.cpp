#include "engine/tools/validation/cases.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include "engine/step/kernels.h"
#include "engine/step/simulation.h"
#include "materials/water.h"

namespace mpm::validation {

const Measure& Outcome::measure(const std::string& name) const {
  for (const Measure& m : measures)
    if (m.name == name) return m;
  throw std::out_of_range("no measure '" + name + "'");
}

Vec3 linear_momentum(const Simulation& sim) {
  const Particles& p = sim.particles();
  Vec3 P = Vec3::Zero();
  for (std::size_t q = 0; q < p.size(); ++q) P += p.mass(q) * p.v[q];
  return P;
}

Vec3 angular_momentum(const Simulation& sim) {
  const Particles& p = sim.particles();
  const Grid& g = sim.grid();
  const bool apic = !p.C.empty();
  Vec3 L = Vec3::Zero();
  for (std::size_t q = 0; q < p.size(); ++q) {
    L += p.mass(q) * p.x[q].cross(p.v[q]);
    if (!apic) continue;
    // D_p = sum_i w_ip (x_i - x_p)(x_i - x_p)^T of the scene's kernel.
    const Mat3 D = dispatch_kernel(sim.scene().simulation.kernel, [&]<Kernel K>() {
      constexpr int N = KernelTraits<K>::kNodes;
      const auto s = make_stencil<K>(p.x[q], g.origin, g.inv_h);
      Mat3 d = Mat3::Zero();
      for (int i = 0; i < N; ++i)
        for (int j = 0; j < N; ++j)
          for (int k = 0; k < N; ++k) {
            const Vec3 r = g.position(s.base.x() + i, s.base.y() + j, s.base.z() + k) - p.x[q];
            d += s.weight(i, j, k) * r * r.transpose();
          }
      return d;
    });
    const Mat3 B = to_real(p.C[q]) * D;  // L_a += m eps_abc B_cb
    L += p.mass(q) * Vec3(B(2, 1) - B(1, 2), B(0, 2) - B(2, 0), B(1, 0) - B(0, 1));
  }
  return L;
}

namespace {

/// The box a unit-cube mesh (scenes/meshes/cube.obj) fills after the object's scale and offset.
struct Box {
  Vec3 min, max;
};
Box cube_box(const ObjectDesc& o) {
  if (o.rotation_deg.norm() != 0 || o.mesh.filename() != "cube.obj")
    throw std::invalid_argument("validation object '" + o.name +
                                "' must be meshes/cube.obj without rotation");
  return {o.offset - 0.5 * o.scale.cwiseAbs(), o.offset + 0.5 * o.scale.cwiseAbs()};
}

double param(const ObjectDesc& o, const std::string& key) {
  const auto it = o.params.find(key);
  if (it == o.params.end()) throw std::invalid_argument("object has no parameter " + key);
  return it->second;
}

/// Cauchy stress sigma = tau / J of particle q at its current F, from its material group's
/// compute_stress (the step need not store the stress: the SIMD scatter folds it in).
Mat3 cauchy_stress(const Simulation& sim, std::size_t q) {
  const Particles& p = sim.particles();
  for (const MaterialRange& m : sim.materials())
    if (q >= m.first && q < m.first + m.count) {
      StoredMat3 neg_v0_tau;
      m.material->compute_stress(std::span<const StoredMat3>(&p.F[q], 1), p.volume0(q),
                                 std::span<StoredMat3>(&neg_v0_tau, 1));
      return -to_real(neg_v0_tau) / (p.volume0(q) * to_real(p.F[q]).determinant());
    }
  throw std::logic_error("particle " + std::to_string(q) + " lies in no material range");
}

/// Mass-weighted mean of a per-particle vector `field` (e.g. Particles::x) over one object.
Vec3 object_mean(const Simulation& sim, std::size_t object, std::vector<Vec3> Particles::*field) {
  const ObjectInfo& o = sim.objects()[object];
  const Particles& p = sim.particles();
  Vec3 sum = Vec3::Zero();
  for (std::size_t q = o.first; q < o.first + o.count; ++q) sum += p.mass(q) * (p.*field)[q];
  return sum / o.mass;
}

Vec3 centroid(const Simulation& sim, std::size_t object) {
  return object_mean(sim, object, &Particles::x);
}

Vec3 mean_velocity(const Simulation& sim, std::size_t object) {
  return object_mean(sim, object, &Particles::v);
}

double rms(const std::vector<double>& e) {
  double s = 0;
  for (double x : e) s += x * x;
  return e.empty() ? 0 : std::sqrt(s / e.size());
}

/// Where each particle is in memory, by id. The reorder stage moves particles in memory
/// (simulation.reorder_every), so a probe that remembers particles keeps their ids.
std::vector<std::size_t> index_by_id(const Particles& p) {
  std::vector<std::size_t> at(p.size());
  for (std::size_t q = 0; q < p.size(); ++q) at[p.id[q]] = q;
  return at;
}

/// 1. Free fall and projectile: x(t) = x0 + v0 t + g t^2 / 2 for every object's centre of mass.
/// Symplectic Euler with a fixed dt lands at x(t) + g dt t / 2 exactly, reported as
/// "scheme_error".
class FreeFall final : public Probe {
 public:
  void on_start(const Simulation& sim, int) override {
    for (std::size_t o = 0; o < sim.objects().size(); ++o) {
      x0_.push_back(centroid(sim, o));
      v0_.push_back(mean_velocity(sim, o));
    }
  }
  void score(const Simulation& sim, Outcome& out) override {
    const double t = sim.time();
    const Vec3 g = sim.scene().simulation.gravity;
    double err = 0, travel = 0;
    for (std::size_t o = 0; o < x0_.size(); ++o) {
      const Vec3 exact = x0_[o] + v0_[o] * t + 0.5 * g * t * t;
      err = std::max(err, (centroid(sim, o) - exact).norm());
      travel = std::max(travel, (exact - x0_[o]).norm());
    }
    out.error_name = "centre-of-mass position error / distance travelled";
    out.error = err / travel;
    out.measures.push_back({"position_error", err, 0, "m"});
    if (const auto& dt = sim.scene().simulation.dt; dt && !sim.scene().simulation.cfl)
      out.measures.push_back({"scheme_error", err, 0.5 * g.norm() * *dt * t, "m"});
  }

 private:
  std::vector<Vec3> x0_, v0_;
};

/// 2. An elastic block (nu = 0) settled on a sticky floor: sigma_yy(Y) = -rho g (H - Y) and
/// u_y(Y) = -(rho g / E) (H Y - Y^2 / 2) in the reference height Y above the floor. With nu = 0
/// both are exact for fixed corotated at any strain (sigma = E (lambda - 1) in uniaxial strain).
class RestingColumn final : public Probe {
 public:
  void on_start(const Simulation& sim, int) override {
    const Particles& p = sim.particles();
    X0_.resize(p.size());
    for (std::size_t q = 0; q < p.size(); ++q) X0_[p.id[q]] = p.x[q];
  }
  void score(const Simulation& sim, Outcome& out) override {
    const ObjectDesc& od = sim.scene().objects.at(0);
    const Box box = cube_box(od);
    const double H = box.max.y() - box.min.y();
    const double rho = sim.objects()[0].density, E = param(od, "E");
    const double g = -sim.scene().simulation.gravity.y();
    const double u_top = rho * g * H * H / (2 * E);
    const Particles& p = sim.particles();
    std::vector<double> du, dsig;
    double top_u = 0, top_exact = 0;
    int top = 0;
    for (std::size_t q = 0; q < p.size(); ++q) {
      const Vec3& X = X0_[p.id[q]];
      const double Y = X.y() - box.min.y();
      const double u_exact = -(rho * g / E) * (H * Y - 0.5 * Y * Y);
      const double u = p.x[q].y() - X.y();
      du.push_back((u - u_exact) / u_top);
      dsig.push_back((cauchy_stress(sim, q)(1, 1) + rho * g * (H - Y)) / (rho * g * H));
      if (Y > 0.9 * H) top_u += u, top_exact += u_exact, ++top;
    }
    out.error_name = "settled height error / exact settlement";
    out.error = std::abs(top_u - top_exact) / top / u_top;
    out.measures.push_back({"top_settlement", -top_u / top, -top_exact / top, "m"});
    out.measures.push_back({"displacement_rms_error", rms(du), 0, ""});
    out.measures.push_back({"stress_rms_error", rms(dsig), 0, ""});
  }

 private:
  std::vector<Vec3> X0_;  // reference position, by particle id
};

/// 3. A free-free bar along x (nu = 0) given v = a (x - centre): its first mode has period
/// T = 2 L / sqrt(E / rho). The mode is tracked as q(t) = sum_p m_p u_x,p cos(pi X_p / L), whose
/// zero crossings fall at k T / 2; energy drift is (E(t) - E(0)) / E(0).
class BarVibration final : public Probe {
 public:
  void on_start(const Simulation& sim, int) override {
    const Particles& p = sim.particles();
    box_ = cube_box(sim.scene().objects.at(0));
    const double L = box_.max.x() - box_.min.x();
    X0_.resize(p.size());
    mode_.resize(p.size());
    for (std::size_t i = 0; i < p.size(); ++i) {  // q = sum_p w_p (x_p - X_p), fixed weights
      X0_[p.id[i]] = p.x[i].x();
      mode_[p.id[i]] = p.mass(i) * std::cos(M_PI * (p.x[i].x() - box_.min.x()) / L);
    }
    energy0_ = sim.total_energy();
    energy_.name = "energy / initial energy";
    energy_.t.push_back(0);
    energy_.value.push_back(1);
  }
  void on_substep(const Simulation& sim, int) override {
    const Particles& p = sim.particles();
    double q = 0;
    for (std::size_t i = 0; i < p.size(); ++i)
      q += mode_[p.id[i]] * (p.x[i].x() - X0_[p.id[i]]);
    const double t = sim.time();
    if (!q_.empty() && q_.back() != 0 && q != 0 && (q_.back() > 0) != (q > 0))
      crossings_.push_back(t_.back() + (t - t_.back()) * q_.back() / (q_.back() - q));
    t_.push_back(t);
    q_.push_back(q);
  }
  void on_frame(const Simulation& sim, int) override {
    energy_.t.push_back(sim.time());
    energy_.value.push_back(sim.total_energy() / energy0_);
  }
  void score(const Simulation& sim, Outcome& out) override {
    const ObjectDesc& od = sim.scene().objects.at(0);
    const double L = box_.max.x() - box_.min.x();
    const double T_exact = 2 * L / std::sqrt(param(od, "E") / sim.objects()[0].density);
    // Least-squares fit of crossing k at k T / 2.
    double sk2 = 0, skt = 0;
    for (std::size_t k = 0; k < crossings_.size(); ++k) {
      sk2 += (k + 1.0) * (k + 1.0);
      skt += (k + 1.0) * crossings_[k];
    }
    const double T = crossings_.empty() ? 0 : 2 * skt / sk2;
    out.error_name = "first-mode period relative error";
    out.error = crossings_.empty() ? 1 : std::abs(T - T_exact) / T_exact;
    out.measures.push_back({"period", T, T_exact, "s"});
    out.measures.push_back({"half_periods_seen", double(crossings_.size()), 0, ""});
    out.measures.push_back({"energy_drift", sim.total_energy() / energy0_ - 1, 0, ""});
    out.series.push_back(energy_);
  }

 private:
  std::vector<double> X0_, mode_;  // reference x, and m cos(pi X / L), by particle id
  Box box_;
  double energy0_ = 0;
  std::vector<double> t_, q_, crossings_;
  Series energy_;
};

/// 4. Two elastic spheres colliding head-on (after Sulsky, Chen, Schreyer 1994, section 5):
/// linear momentum is conserved to round-off; kinetic energy dips in contact and recovers;
/// the spheres separate.
class Collision final : public Probe {
 public:
  void on_start(const Simulation& sim, int) override {
    P0_ = linear_momentum(sim);
    ke0_ = ke_min_ = sim.kinetic_energy();
    const ObjectInfo& o = sim.objects()[0];
    scale_ = o.mass * mean_velocity(sim, 0).norm();
    kinetic_.name = "kinetic energy / initial";
    kinetic_.t.push_back(0);
    kinetic_.value.push_back(1);
  }
  void on_substep(const Simulation& sim, int) override {
    drift_ = std::max(drift_, (linear_momentum(sim) - P0_).norm() / scale_);
    ke_min_ = std::min(ke_min_, sim.kinetic_energy());
  }
  void on_frame(const Simulation& sim, int) override {
    kinetic_.t.push_back(sim.time());
    kinetic_.value.push_back(sim.kinetic_energy() / ke0_);
  }
  void score(const Simulation& sim, Outcome& out) override {
    const Vec3 d = centroid(sim, 1) - centroid(sim, 0);
    const Vec3 dv = mean_velocity(sim, 1) - mean_velocity(sim, 0);
    out.error_name = "largest linear momentum drift / momentum of one sphere";
    out.error = drift_;
    out.measures.push_back({"momentum_drift", drift_, 0, ""});
    out.measures.push_back({"kinetic_min_ratio", ke_min_ / ke0_, 1, ""});
    out.measures.push_back({"kinetic_end_ratio", sim.kinetic_energy() / ke0_, 1, ""});
    out.measures.push_back({"separating_speed", dv.dot(d.normalized()), 0, "m/s"});
    out.series.push_back(kinetic_);
  }

 private:
  Vec3 P0_;
  double ke0_ = 0, ke_min_ = 0, scale_ = 1, drift_ = 0;
  Series kinetic_;
};

/// 5. A spinning cube without gravity: APIC keeps the total angular momentum to round-off
/// (Jiang et al. 2015, section 5.3); PIC loses it; FLIP lies between.
class SpinningCube final : public Probe {
 public:
  void on_start(const Simulation& sim, int) override {
    L0_ = angular_momentum(sim);
    series_.name = "angular momentum / initial";
    series_.t.push_back(0);
    series_.value.push_back(1);
  }
  void on_frame(const Simulation& sim, int) override {
    series_.t.push_back(sim.time());
    series_.value.push_back(angular_momentum(sim).dot(L0_) / L0_.squaredNorm());
  }
  void score(const Simulation& sim, Outcome& out) override {
    const Vec3 L = angular_momentum(sim);
    out.error_name = "angular momentum drift |L - L0| / |L0|";
    out.error = (L - L0_).norm() / L0_.norm();
    out.measures.push_back({"angular_momentum_ratio", L.dot(L0_) / L0_.squaredNorm(), 1, ""});
    out.series.push_back(series_);
  }

 private:
  Vec3 L0_;
  Series series_;
};

/// Uniaxial Cauchy stress of the compressible Neo-Hookean model of materials/neo_hookean.h
/// (tau = mu (F F^T - I) + lambda ln J I) at axial stretch `a`, lateral faces traction-free:
/// the lateral stretch b solves mu (b^2 - 1) + lambda ln(a b^2) = 0 (bisection; it is monotone).
double neo_hookean_uniaxial_stress(double mu, double lambda, double a) {
  double lo = 1e-3, hi = 1e3;
  for (int i = 0; i < 200; ++i) {
    const double b = 0.5 * (lo + hi);
    (mu * (b * b - 1) + lambda * std::log(a * b * b) > 0 ? hi : lo) = b;
  }
  const double b = 0.5 * (lo + hi), J = a * b * b;
  return (mu * (a * a - 1) + lambda * std::log(J)) / J;
}

/// 6. A Neo-Hookean block squeezed between two slip walls: mean sigma_yy against the uniaxial
/// answer at the measured stretch. Both are taken away from the walls, whose grid nodes act on
/// the particles within 1.5 cells: the stretch from two bands of particles at 20-30 % and
/// 70-80 % of the reference height, the stress as the mean over the particles between them.
class UniaxialCompression final : public Probe {
 public:
  void on_start(const Simulation& sim, int) override {
    const Particles& p = sim.particles();
    double lo = 1e300, hi = -1e300;
    for (const Vec3& x : p.x) lo = std::min(lo, x.y()), hi = std::max(hi, x.y());
    for (std::size_t q = 0; q < p.size(); ++q) {
      const double Y = (p.x[q].y() - lo) / (hi - lo);
      if (Y > 0.2 && Y < 0.3) lower_.push_back(p.id[q]);
      if (Y > 0.7 && Y < 0.8) upper_.push_back(p.id[q]);
      if (Y > 0.2 && Y < 0.8) middle_.push_back(p.id[q]);
    }
    gap0_ = gap(sim);
    stress_.name = "mean sigma_yy / exact";
  }
  void on_frame(const Simulation& sim, int) override {
    const auto [s, exact] = stresses(sim);
    stress_.t.push_back(sim.time());
    stress_.value.push_back(s / exact);
  }
  void score(const Simulation& sim, Outcome& out) override {
    const auto [s, exact] = stresses(sim);
    out.error_name = "mean axial stress relative error at the final stretch";
    out.error = std::abs(s - exact) / std::abs(exact);
    out.measures.push_back({"stretch", gap(sim) / gap0_, 0, ""});
    out.measures.push_back({"sigma_yy", s, exact, "Pa"});
    out.series.push_back(stress_);
  }

 private:
  double mean_y(const Simulation& sim, const std::vector<std::size_t>& band) const {
    const std::vector<std::size_t> at = index_by_id(sim.particles());
    double y = 0;
    for (std::size_t id : band) y += sim.particles().x[at[id]].y();
    return y / band.size();
  }
  double gap(const Simulation& sim) const { return mean_y(sim, upper_) - mean_y(sim, lower_); }
  std::pair<double, double> stresses(const Simulation& sim) const {
    const ObjectDesc& od = sim.scene().objects.at(0);
    const Lame lame = lame_from_young(param(od, "E"), param(od, "nu"));
    const std::vector<std::size_t> at = index_by_id(sim.particles());
    double s = 0;
    for (std::size_t id : middle_) s += cauchy_stress(sim, at[id])(1, 1);
    return {s / middle_.size(), neo_hookean_uniaxial_stress(lame.mu, lame.lambda, gap(sim) / gap0_)};
  }
  std::vector<std::size_t> lower_, upper_, middle_;  // particle ids
  double gap0_ = 1;
  Series stress_;
};

/// The incline of cases 7-9: the scene's first wall is a plane floor, and gravity is tilted
/// against it. Splits g into its part into the floor, g_n = -g . n, and its part along it,
/// |g_t| down the slope s (references.md, "Contact and friction").
struct Incline {
  Vec3 normal, down_slope;   ///< Floor normal (unit, into the free side), slope direction.
  double g_n = 0, g_t = 0;   ///< Gravity into the floor and along it, m/s^2.
  double friction = 0;       ///< The floor's Coulomb coefficient.
  Vec3 point;                ///< A point on the floor.

  explicit Incline(const SceneDesc& scene) {
    if (scene.walls.empty() || scene.walls[0].shape != WallDesc::Shape::plane)
      throw std::invalid_argument("incline case needs a plane wall first");
    const WallDesc& w = scene.walls[0];
    normal = w.normal.normalized();
    point = w.point;
    friction = w.friction;
    const Vec3 g = scene.simulation.gravity;
    g_n = -g.dot(normal);
    const Vec3 gt = g + g_n * normal;
    g_t = gt.norm();
    down_slope = g_t > 0 ? Vec3(gt / g_t) : Vec3::Zero();
  }
  /// tan of the slope angle.
  double tan_slope() const { return g_t / g_n; }
};

/// 7 and 8. A block on an incline, at rest at the start: it slides x = a t^2 / 2 with
/// a = g (sin theta - mu cos theta) if mu < tan theta, and stays if mu >= tan theta (Coulomb).
/// Sliding is scored by the relative error of the distance; sticking by the distance itself.
class InclineBlock final : public Probe {
 public:
  void on_start(const Simulation& sim, int) override {
    x0_ = centroid(sim, 0);
    series_.name = "distance down the slope, m";
    series_.t.push_back(0);
    series_.value.push_back(0);
  }
  void on_frame(const Simulation& sim, int) override {
    series_.t.push_back(sim.time());
    series_.value.push_back((centroid(sim, 0) - x0_).dot(Incline(sim.scene()).down_slope));
  }
  void score(const Simulation& sim, Outcome& out) override {
    const Incline in(sim.scene());
    const double t = sim.time();
    const double a = std::max(0.0, in.g_t - in.friction * in.g_n);
    const Vec3 d = centroid(sim, 0) - x0_;
    const double dist = d.dot(in.down_slope), exact = 0.5 * a * t * t;
    if (a > 0) {
      out.error_name = "distance slid relative error";
      out.error = std::abs(dist - exact) / exact;
    } else {
      out.error_name = "distance slid (exact 0), m";
      out.error = std::abs(dist);
    }
    out.measures.push_back({"distance", dist, exact, "m"});
    out.measures.push_back({"speed", mean_velocity(sim, 0).dot(in.down_slope), a * t, "m/s"});
    out.measures.push_back({"normal_displacement", d.dot(in.normal), 0, "m"});
    out.series.push_back(series_);
  }

 private:
  Vec3 x0_;
  Series series_;
};

/// 9. A solid ball on an incline rolls without slipping if mu >= (2/7) tan theta:
/// x = (5/7) g sin theta t^2 / 2 (I = (2/5) m R^2). The slip ratio is the contact point's speed
/// down the slope over the centre's: 0 rolling, 1 sliding without spin. The spin is
/// omega = I^-1 L about the centroid from the particles (APIC's affine part left out).
class RollingBall final : public Probe {
 public:
  void on_start(const Simulation& sim, int) override {
    const Incline in(sim.scene());
    x0_ = centroid(sim, 0);
    radius_ = (x0_ - in.point).dot(in.normal);  // the centre's height above the floor
    series_.name = "distance / exact rolling distance";
  }
  void on_frame(const Simulation& sim, int) override {
    const double t = sim.time();
    series_.t.push_back(t);
    series_.value.push_back((centroid(sim, 0) - x0_).dot(Incline(sim.scene()).down_slope) /
                            (0.5 * acceleration(sim) * t * t));
  }
  void score(const Simulation& sim, Outcome& out) override {
    const Incline in(sim.scene());
    const double t = sim.time();
    const double exact = 0.5 * acceleration(sim) * t * t;
    const double dist = (centroid(sim, 0) - x0_).dot(in.down_slope);
    const Vec3 c = centroid(sim, 0), vc = mean_velocity(sim, 0);
    const Particles& p = sim.particles();
    const ObjectInfo& o = sim.objects()[0];
    Mat3 I = Mat3::Zero();
    Vec3 L = Vec3::Zero();
    for (std::size_t q = o.first; q < o.first + o.count; ++q) {
      const Vec3 r = p.x[q] - c;
      I += p.mass(q) * (r.squaredNorm() * Mat3::Identity() - r * r.transpose());
      L += p.mass(q) * r.cross(p.v[q] - vc);
    }
    const Vec3 omega = I.ldlt().solve(L);
    const Vec3 contact = vc + omega.cross(-radius_ * in.normal);
    const double v = vc.dot(in.down_slope);
    out.error_name = "distance rolled relative error";
    out.error = std::abs(dist - exact) / exact;
    out.measures.push_back({"distance", dist, exact, "m"});
    out.measures.push_back({"speed", v, acceleration(sim) * t, "m/s"});
    out.measures.push_back({"slip_ratio", contact.dot(in.down_slope) / v, 0, ""});
    // The sampled ball's own I / (m R^2) about the rolling axis, R the centre's height above
    // the floor: 2/5 for a solid ball.
    const Vec3 axis = in.normal.cross(in.down_slope);
    out.measures.push_back({"inertia_ratio", axis.dot(I * axis) / (o.mass * radius_ * radius_),
                            0.4, ""});
    out.series.push_back(series_);
  }

 private:
  /// (5/7) g sin theta when friction can hold the contact, else the sliding ball's
  /// g (sin theta - mu cos theta).
  static double acceleration(const Simulation& sim) {
    const Incline in(sim.scene());
    if (in.friction >= 2.0 / 7.0 * in.tan_slope()) return 5.0 / 7.0 * in.g_t;
    return in.g_t - in.friction * in.g_n;
  }
  Vec3 x0_;
  double radius_ = 0;
  Series series_;
};

/// 10. Tait water at rest in a box: p = rho0 g (H - Y) at reference height Y, with p read from
/// each particle's J (p = K / gamma (J^-gamma - 1)). Mass above a particle per unit area is
/// rho0 (H - Y) however the water is compressed, so the answer is exact in reference heights.
/// The grid sees the pressure only through cell-sized weights, so the score is the pressure
/// averaged over layers one cell thick (by reference height); the particle-to-particle
/// scatter inside a layer, which the grid cannot see and so cannot damp, is reported apart.
class HydrostaticWater final : public Probe {
 public:
  void on_start(const Simulation& sim, int) override {
    const Particles& p = sim.particles();
    Y0_.resize(p.size());
    for (std::size_t q = 0; q < p.size(); ++q) Y0_[p.id[q]] = p.x[q].y();
  }
  void score(const Simulation& sim, Outcome& out) override {
    const ObjectDesc& od = sim.scene().objects.at(0);
    const Box box = cube_box(od);
    const double H = box.max.y() - box.min.y(), h = sim.scene().grid.spacing().y();
    const double rho = sim.objects()[0].density, g = -sim.scene().simulation.gravity.y();
    const materials::TaitWater water{param(od, "bulk_modulus"), param(od, "gamma")};
    const Particles& p = sim.particles();
    const int layers = std::max(1, static_cast<int>(std::lround(H / h)));
    std::vector<double> sum(layers, 0), sum_exact(layers, 0), sum_sq(layers, 0);
    std::vector<int> count(layers, 0);
    // The exact pressure under the water that was sampled: the weight of the particles above a
    // particle's reference height (half of those level with it) over the floor's area. The
    // lattice tied to the grid fills the box to within a particle spacing, by a count that
    // depends on where the box lies between the node rows; rho g (H - Y) is the full box's.
    std::vector<double> heights(Y0_);
    std::sort(heights.begin(), heights.end());
    const double area = (box.max.x() - box.min.x()) * (box.max.z() - box.min.z());
    const double weight = sim.particles().mass(0) * g / area;
    for (std::size_t q = 0; q < p.size(); ++q) {
      const double Y0 = Y0_[p.id[q]];
      const double Y = Y0 - box.min.y();
      const int k = std::clamp(static_cast<int>(Y / H * layers), 0, layers - 1);
      const double pressure = water.pressure(to_real(p.F[q]).determinant());
      const auto [lo, hi] = std::equal_range(heights.begin(), heights.end(), Y0);
      const double above = static_cast<double>(heights.end() - hi) + 0.5 * (hi - lo - 1);
      sum[k] += pressure;
      sum_sq[k] += pressure * pressure;
      sum_exact[k] += weight * above;
      ++count[k];
    }
    std::vector<double> layer_error, scatter;
    Series profile{"layer pressure / rho g H against depth (H - Y) / H", {}, {}};
    for (int k = 0; k < layers; ++k) {
      if (count[k] == 0) continue;
      const double mean = sum[k] / count[k], exact = sum_exact[k] / count[k];
      layer_error.push_back((mean - exact) / (rho * g * H));
      scatter.push_back(std::sqrt(std::max(0.0, sum_sq[k] / count[k] - mean * mean)) /
                        (rho * g * H));
      profile.t.push_back(exact / (rho * g * H));
      profile.value.push_back(mean / (rho * g * H));
    }
    out.error_name = "layer-mean pressure RMS error / rho g H";
    out.error = rms(layer_error);
    double worst = 0;  // the largest layer error relative to the layer's own pressure
    for (int k = 0; k < layers; ++k)
      if (count[k] > 0) worst = std::max(worst, std::abs(sum[k] / sum_exact[k] - 1));
    out.measures.push_back({"worst_layer_error", worst, 0, ""});
    out.measures.push_back({"bottom_pressure", sum[0] / count[0], sum_exact[0] / count[0], "Pa"});
    out.measures.push_back({"particle_scatter", rms(scatter), 0, ""});
    out.series.push_back(profile);
  }

 private:
  std::vector<double> Y0_;  // reference height, by particle id
};

/// Martin & Moyce 1952, "An experimental study of the collapse of liquid columns on a rigid
/// horizontal plane", Phil. Trans. R. Soc. A 244, 312-324: surge front Z = x / a against
/// T = t sqrt(2 g / a) for n^2 = 2 (height 2a) and a = 2.25 in, their Figure 3, as digitised in
/// PySPH (pysph/examples/db_exp_data.py, mm_data_2), the points with Z < 6 (our tank).
constexpr double kMartinMoyceT[] = {0.832, 1.219, 1.997, 2.547, 3.345, 4.034, 4.418};
constexpr double kMartinMoyceZ[] = {1.217, 1.474, 2.292, 2.995, 4.134, 4.944, 5.881};

/// 11. Dam break: the surge front of a collapsing water column against Martin & Moyce 1952.
/// The front is the largest x of any particle (plus the half particle spacing the sampling
/// leaves at the face, measured at the start), Z = (front - left face) / a.
class DamBreak final : public Probe {
 public:
  void on_start(const Simulation& sim, int) override {
    const Box box = cube_box(sim.scene().objects.at(0));
    a_ = box.max.x() - box.min.x();
    x0_ = box.min.x();
    gap_ = box.max.x() - front(sim);
    series_.name = "surge front Z = x / a against T = t sqrt(2 g / a)";
    record(sim);
  }
  void on_frame(const Simulation& sim, int) override { record(sim); }
  void score(const Simulation& sim, Outcome& out) override {
    Series data{"Martin & Moyce 1952, n^2 = 2", {}, {}};
    std::vector<double> rel;
    for (std::size_t k = 0; k < std::size(kMartinMoyceT); ++k) {
      const double T = kMartinMoyceT[k];
      if (T > series_.t.back()) break;
      const auto hi = std::lower_bound(series_.t.begin(), series_.t.end(), T);
      const std::size_t i = std::max<std::size_t>(1, hi - series_.t.begin());
      const double w = (T - series_.t[i - 1]) / (series_.t[i] - series_.t[i - 1]);
      const double Z = (1 - w) * series_.value[i - 1] + w * series_.value[i];
      rel.push_back((Z - kMartinMoyceZ[k]) / kMartinMoyceZ[k]);
      data.t.push_back(T);
      data.value.push_back(kMartinMoyceZ[k]);
      out.measures.push_back({"Z_at_T" + std::to_string(k), Z, kMartinMoyceZ[k], ""});
    }
    out.error_name = "surge front RMS relative error against Martin & Moyce 1952";
    out.error = rms(rel);
    out.series.push_back(series_);
    out.series.push_back(data);
  }

 private:
  static double front(const Simulation& sim) {
    double x = -1e300;
    for (const Vec3& xp : sim.particles().x) x = std::max(x, xp.x());
    return x;
  }
  void record(const Simulation& sim) {
    const double g = -sim.scene().simulation.gravity.y();
    series_.t.push_back(sim.time() * std::sqrt(2 * g / a_));
    series_.value.push_back((front(sim) + gap_ - x0_) / a_);
  }
  double a_ = 0, x0_ = 0, gap_ = 0;
  Series series_;
};

/// Runout law of Lube, Huppert, Sparks, Freundt 2005 (Phys. Rev. E 72, 041301) for
/// two-dimensional collapses: (L - L0) / L0 = 1.2 a for a < 1.8 and 1.9 a^(2/3) for a > 2.8
/// (between, the nearer regime: 1.2 a up to a = 2.3).
double lube_runout(double a) {
  return a <= 2.3 ? 1.2 * a : 1.9 * std::pow(a, 2.0 / 3);
}

/// Final height law of Lube et al. 2005 (2D): H / L0 = a for a < 1.15, a^(2/5) above.
double lube_height(double a) {
  return a < 1.15 ? a : std::pow(a, 0.4);
}

/// Angle (degrees) of the shear-flow friction tau / sigma_n = 3 alpha / sqrt 2 =
/// 2 sqrt 3 sin(phi) / (3 - sin(phi)) that Klar et al. 2016's cone (alpha, their section 7.3)
/// gives in plane strain for friction angle `phi_deg`: steady simple shear with no dilatancy has
/// a pure-shear stress deviator, |dev tau| = sqrt 2 tau, and the cone is |dev tau| = 3 alpha
/// sigma_n. A cohesionless slope in this material stands up to this angle (docs/validation.md,
/// case 12); 34.7 degrees for phi = 30.
double flow_friction_angle(double phi_deg) {
  const double s = std::sin(phi_deg * std::numbers::pi / 180);
  return std::atan(2 * std::sqrt(3.0) * s / (3 - s)) * 180 / std::numbers::pi;
}

/// 12. Granular column collapse: symmetric sand columns of half-width L0 and aspect a = H / L0
/// (one per object) collapse on a rough floor; the final runout (L - L0) / L0 of each side
/// and the final height H / L0 against Lube et al. 2005. Extents are particle extents plus the
/// gap the sampling leaves at each face (measured at the start).
class ColumnCollapse final : public Probe {
 public:
  void on_start(const Simulation& sim, int) override {
    for (std::size_t o = 0; o < sim.objects().size(); ++o) {
      const Box box = cube_box(sim.scene().objects.at(o));
      const Extent e = extent(sim, o);
      Column c;
      c.half_width = 0.5 * (box.max.x() - box.min.x());
      c.height = box.max.y() - box.min.y();
      c.centre = 0.5 * (box.min.x() + box.max.x());
      c.floor = box.min.y();
      c.gap_x = box.max.x() - e.max_x;
      c.gap_y = box.max.y() - e.max_y;
      columns_.push_back(c);
    }
  }
  void score(const Simulation& sim, Outcome& out) override {
    std::vector<double> rel;
    for (std::size_t o = 0; o < columns_.size(); ++o) {
      const Column& c = columns_[o];
      const Extent e = extent(sim, o);
      const double a = c.height / c.half_width;
      const double right = e.max_x + c.gap_x - c.centre, left = c.centre - (e.min_x - c.gap_x);
      const double runout = (0.5 * (left + right) - c.half_width) / c.half_width;
      const double height = (e.max_y + c.gap_y - c.floor) / c.half_width;
      const std::string name = sim.objects()[o].name;
      out.measures.push_back({"runout_" + name, runout, lube_runout(a), ""});
      out.measures.push_back({"height_" + name, height, lube_height(a), ""});
      out.measures.push_back(
          {"slope_" + name, flank_slope(sim, o, c),
           flow_friction_angle(param(sim.scene().objects.at(o), "friction_angle")), "deg"});
      rel.push_back((runout - lube_runout(a)) / lube_runout(a));
    }
    out.error_name = "runout RMS relative error against Lube et al. 2005";
    out.error = rms(rel);
  }

 private:
  struct Extent {
    double min_x = 1e300, max_x = -1e300, max_y = -1e300;
  };
  struct Column {
    double half_width = 0, height = 0, centre = 0, floor = 0, gap_x = 0, gap_y = 0;
  };
  /// Slope (degrees) of the deposit's flank: the surface height (highest particle per h-wide
  /// bin of |x - centre|, both sides folded) fitted by a line where it is between 20 % and
  /// 80 % of the top; NaN with fewer than three such bins.
  static double flank_slope(const Simulation& sim, std::size_t o, const Column& c) {
    const ObjectInfo& info = sim.objects()[o];
    const double h = sim.scene().grid.spacing().x();
    std::vector<double> top;
    for (std::size_t q = info.first; q < info.first + info.count; ++q) {
      const Vec3& x = sim.particles().x[q];
      const std::size_t b = static_cast<std::size_t>(std::abs(x.x() - c.centre) / h);
      if (b >= top.size()) top.resize(b + 1, 0);
      top[b] = std::max(top[b], x.y() + c.gap_y - c.floor);
    }
    const double peak = *std::max_element(top.begin(), top.end());
    double n = 0, sr = 0, sy = 0, srr = 0, sry = 0;
    for (std::size_t b = 0; b < top.size(); ++b) {
      if (!(top[b] > 0.2 * peak && top[b] < 0.8 * peak)) continue;
      const double r = (b + 0.5) * h;
      n += 1, sr += r, sy += top[b], srr += r * r, sry += r * top[b];
    }
    if (n < 3) return std::nan("");
    const double slope = (n * sry - sr * sy) / (n * srr - sr * sr);
    return -std::atan(slope) * 180 / std::numbers::pi;
  }
  static Extent extent(const Simulation& sim, std::size_t o) {
    const ObjectInfo& info = sim.objects()[o];
    Extent e;
    for (std::size_t q = info.first; q < info.first + info.count; ++q) {
      const Vec3& x = sim.particles().x[q];
      e.min_x = std::min(e.min_x, x.x());
      e.max_x = std::max(e.max_x, x.x());
      e.max_y = std::max(e.max_y, x.y());
    }
    return e;
  }
  std::vector<Column> columns_;
};

template <class P>
Probe* make() {
  return new P;
}

}  // namespace

const std::vector<Case>& cases() {
  static const std::vector<Case> all = {
      {"free_fall", "centre of mass of a dropped and a thrown block against x0 + v0 t + g t^2 / 2",
       make<FreeFall>},
      {"resting_column", "settled block on a sticky floor against sigma_yy = -rho g (H - Y)",
       make<RestingColumn>},
      {"bar_vibration", "free-free bar's first-mode period against T = 2 L / sqrt(E / rho)",
       make<BarVibration>},
      {"sphere_collision", "two elastic spheres head-on: momentum, kinetic energy, separation",
       make<Collision>},
      {"spinning_cube", "angular momentum of a spinning cube with no gravity", make<SpinningCube>},
      {"uniaxial_compression", "Neo-Hookean block between slip walls against uniaxial stress",
       make<UniaxialCompression>},
      {"sliding_block",
       "block on a 30 degree incline, friction 0.2, against x = g (sin - mu cos) t^2 / 2",
       make<InclineBlock>},
      {"sticking_block", "block on a 30 degree incline, friction 0.8 > tan 30: it stays",
       make<InclineBlock>},
      {"wide_sliding_block", "a block twice as wide, friction 0.2 (issue 30's offset study)",
       make<InclineBlock>},
      {"wide_sticking_block", "a block twice as wide, friction 0.8 (issue 30's offset study)",
       make<InclineBlock>},
      {"rolling_ball", "solid ball on a 30 degree incline against x = (5/7) g sin t^2 / 2",
       make<RollingBall>},
      {"hydrostatic_water", "Tait water at rest in a box: p from J against rho g (H - Y)",
       make<HydrostaticWater>},
      {"hydrostatic_column",
       "a water column at rest, H / h = 8 (the h sweep's scene): p from J against rho g (H - Y)",
       make<HydrostaticWater>},
      {"dam_break", "water column collapse: surge front against Martin & Moyce 1952",
       make<DamBreak>},
      {"column_collapse", "sand columns, a = 0.5 to 8: runout and height against Lube et al. 2005",
       make<ColumnCollapse>},
      {"sand_slope", "a sand column (a = 2) slumps: its deposit's flank slope against phi",
       make<ColumnCollapse>},
  };
  return all;
}

const Case* find_case(const std::string& name) {
  for (const Case& c : cases())
    if (c.name == name) return &c;
  return nullptr;
}

std::filesystem::path scene_path(const Case& c) {
  return std::filesystem::path(MPM_SOURCE_DIR) / "scenes" / "validation" / (c.name + ".yaml");
}

Outcome run_case(const Case& c, const std::vector<SceneOverride>& overrides) {
  MaterialRegistry registry = builtin_registry();
  const SceneDesc scene =
      load_scene(scene_path(c), registry, LoadOptions{overrides, false, {}});
  std::unique_ptr<Simulation> sim = Simulation::create(scene, registry);
  std::unique_ptr<Probe> probe(c.make_probe());
  const RunResult r = run_frames(*sim, scene.simulation.frames, scene.simulation.frame_dt,
                                 {probe.get()});
  Outcome out;
  out.status = status_name(r.status);
  out.particles = sim->particles().size();
  out.substeps = sim->substeps();
  out.seconds = r.loop_seconds;
  probe->score(*sim, out);
  return out;
}

}  // namespace mpm::validation
