#include "apps/runner.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <Eigen/Geometry>
#ifdef _OPENMP
#include <omp.h>
#endif
#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <optional>
#include <regex>

#include "contact/verify/intersection_check.hpp"
#include "contact/verify/obstacle_check.hpp"
#include "framework/build_info.hpp"
#include "framework/checkpoint.hpp"
#include "framework/interrupt.hpp"
#include "framework/obj_io.hpp"
#include "framework/reports.hpp"
#include "framework/writers.hpp"
#include "linear/lapack_info.hpp"
#include "policies/registry.hpp"

namespace weft::app {
namespace {

/// This process's place in an MPI job, from its launcher's environment (Open MPI, MPICH's
/// Hydra, PMI): rank 0 of 1 without mpirun. weft itself makes no MPI call: the linear
/// solver initialises MPI when it distributes the Newton systems (PetscGamg).
struct MpiLaunch {
  int rank = 0, size = 1;
};
MpiLaunch mpi_launch() {
  const auto first = [](std::initializer_list<const char*> names) {
    for (const char* n : names)
      if (const char* v = std::getenv(n)) return std::atoi(v);
    return -1;
  };
  MpiLaunch m;
  const int size = first({"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "SLURM_NTASKS"});
  const int rank = first({"OMPI_COMM_WORLD_RANK", "PMI_RANK", "PMIX_RANK", "SLURM_PROCID"});
  if (size > 1 && rank >= 0 && rank < size) m = {rank, size};
  else if (rank > 0) m = {rank, rank + 1};  // a launcher that gives the rank only: never write as rank 0
  return m;
}

/// Under mpirun every rank runs the same simulation on the same data and the Newton systems
/// are solved by all of them together, so only a linear solver that distributes its solves
/// may run there (every other one would repeat the whole run on each rank).
void require_distributed_solver(const AnySimulator& sim, const MpiLaunch& mpi) {
  if (mpi.size <= 1) return;
  const std::string_view linear = resolve_combo(sim.scene()).linear;
  const Json p = sim.params();
  if (linear == "petsc_gamg" && p.contains("linear") && p["linear"].value("single_process", false))
    throw ConfigError(fmt::format("mpirun with {} ranks: linear.single_process = true solves on each rank alone (every rank would "
                                  "repeat the whole run); set it to false to solve across the ranks",
                                  mpi.size));
  if (linear != "petsc_gamg")
    throw ConfigError(fmt::format("mpirun with {} ranks: combo {} solves its Newton systems with {}, on one process; under mpirun the "
                                  "systems are distributed by linear.solver = petsc_gamg (a build with -DWEFT_WITH_PETSC=ON), the "
                                  "only solver that runs across ranks",
                                  mpi.size, sim.combo(), linear));
}

/// The output directory of a rank other than 0, which writes nothing the user sees: a
/// private temporary directory, removed when the run ends.
struct PrivateOutput {
  std::filesystem::path path;
  explicit PrivateOutput(int rank)
      : path(std::filesystem::temp_directory_path() / fmt::format("weft_rank{}_{}", rank, getpid())) {}
  ~PrivateOutput() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
};

extern "C" void on_signal(int s) { request_stop(s); }

namespace fs = std::filesystem;

/// The exact checks of a cloth run at every frame (contact/verify): cloth-cloth triangle
/// intersections, cloth triangles crossing an obstacle, and the deepest penetration, so that
/// the summary says what the strategy left without a separate benchmark. Untimed in the
/// step statistics (its own `seconds`).
struct ContactAudit {
  int frames = 0, cloth_frames = 0, obstacle_frames = 0;
  std::int64_t max_cloth_pairs = 0, max_obstacle_triangles = 0;
  double deepest = 0, first_time = -1, seconds = 0;
  std::string deepest_obstacle;

  void check(const Scene& scene, const State& s) {
    const auto start = std::chrono::steady_clock::now();
    const std::int64_t pairs = contact::verify::check_self_intersections(s.x, scene.mesh.faces()).num_pairs;
    const contact::verify::ObstacleCheckReport o =
        contact::verify::check_obstacles(s.x, scene.mesh.faces(), scene.spec.obstacles, s.t);
    ++frames;
    cloth_frames += pairs > 0;
    obstacle_frames += o.crossing_triangles > 0;
    max_cloth_pairs = std::max(max_cloth_pairs, pairs);
    max_obstacle_triangles = std::max(max_obstacle_triangles, o.crossing_triangles);
    if ((pairs > 0 || o.crossing_triangles > 0) && first_time < 0) first_time = s.t;
    if (o.deepest > deepest) {
      deepest = o.deepest;
      deepest_obstacle = o.deepest_obstacle;
    }
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  bool clean() const { return cloth_frames == 0 && obstacle_frames == 0; }
  Json to_json() const {
    Json j{{"checked_frames", frames},
           {"frames_with_cloth_intersections", cloth_frames},
           {"max_cloth_intersecting_pairs", max_cloth_pairs},
           {"frames_with_obstacle_crossings", obstacle_frames},
           {"max_obstacle_crossing_triangles", max_obstacle_triangles},
           {"deepest_penetration_m", deepest},
           {"seconds", seconds}};
    if (!deepest_obstacle.empty()) j["deepest_obstacle"] = deepest_obstacle;
    if (first_time >= 0) j["first_time"] = first_time;
    return j;
  }
  std::string line() const {
    if (clean())
      return fmt::format("checked {} frames: no cloth-cloth intersection, no cloth triangle crossing an obstacle", frames);
    return fmt::format("checked {} frames: cloth-cloth intersections in {} (up to {} triangle pairs), obstacle crossings in {} "
                       "(up to {} triangles), deepest penetration {:.3g} m{}, first at t = {} s",
                       frames, cloth_frames, max_cloth_pairs, obstacle_frames, max_obstacle_triangles, deepest,
                       deepest_obstacle.empty() ? "" : " into '" + deepest_obstacle + "'", first_time);
  }
};

// Remove the files a previous run left, so frames of different runs never mix.
void clear_previous_outputs(const fs::path& dir) {
  static const std::regex pattern(
      R"((.+_\d{4,}\.(obj|vtp))|(.+\.pvd)|stats\.jsonl|summary\.json|scene\.json|checkpoint\.wckp|failed_step\.wckp|.+\.tmp)");
  for (const auto& e : fs::directory_iterator(dir))
    if (e.is_regular_file() && std::regex_match(e.path().filename().string(), pattern)) fs::remove(e.path());
}

// On resume: remove the frames after `frame` and return the statistics lines of steps up to
// `step` (stats.jsonl is rewritten with them), so that the directory holds one run.
std::vector<std::string> clear_outputs_after(const fs::path& dir, int frame, long long step) {
  static const std::regex pattern(R"(.+_(\d{4,})\.(obj|vtp))");
  std::smatch m;
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (e.is_regular_file() && std::regex_match(name, m, pattern) && std::stoll(m[1].str()) > frame) fs::remove(e.path());
  }
  std::vector<std::string> kept;
  std::ifstream in(dir / "stats.jsonl");
  for (std::string line; std::getline(in, line);) {
    const Json j = Json::parse(line, nullptr, false);
    if (j.is_object() && j.contains("step") && j["step"].is_number_integer() && j["step"].get<long long>() <= step) kept.push_back(line);
  }
  return kept;
}

// The step a checkpoint's state ends, on this scene's step grid; throws ConfigError when its
// time is not a multiple of time.dt or lies at or after the scene's end.
long long resume_step(const Checkpoint& c, const Scene& scene, const std::string& path) {
  const auto& time = scene.spec.time;
  const std::string kind = scene.spec.rods.empty() ? "cloth" : "rods";
  if (c.header.value("kind", "") != kind)
    throw ConfigError(fmt::format("--resume {}: checkpoint holds a '{}' state; this combination simulates {}", path,
                                  c.header.value("kind", "?"), kind == "rods" ? "rods" : "cloth"));
  if (!c.header.contains("time") || !c.header["time"].is_number()) throw ConfigError(fmt::format("--resume {}: header has no 'time'", path));
  const double t = c.header["time"].get<double>();
  if (!(t >= 0) || !(t / time.dt < 1e15))
    throw ConfigError(fmt::format("--resume {}: its time t = {} s is not a time of a run (valid: 0 <= t < time.duration): the file is damaged", path, t));
  const long long k = std::llround(t / time.dt);
  if (std::abs(static_cast<double>(k) * time.dt - t) > 1e-9 * std::max(t, time.dt))
    throw ConfigError(fmt::format("--resume {}: its time t = {} s is not a multiple of time.dt = {} s (valid: a time.dt that divides t, "
                                  "e.g. the dt of the run that wrote it)",
                                  path, t, time.dt));
  const long long total = time.num_steps();
  if (k >= total)
    throw ConfigError(fmt::format("--resume {}: its time t = {} s is at or after the scene's end, t = {} s ({} frames of {} s for "
                                  "time.duration = {} s): nothing to run; override time.duration to continue",
                                  path, t, static_cast<double>(total) * time.dt, time.num_frames(), 1.0 / time.frame_rate, time.duration));
  return k;
}

// Triangulated obstacle surface at time t, for output only.
MeshData obstacle_mesh(const ObstacleSpec& o, double t) {
  MeshData m;
  if (o.shape == ObstacleShape::sphere) {
    const int nu = 24, nv = 12;
    m.V.resize(nu * (nv - 1) + 2, 3);
    m.V.row(0) = Eigen::RowVector3d(0, 0, -1);
    for (int j = 1; j < nv; ++j)
      for (int i = 0; i < nu; ++i) {
        const double th = M_PI * j / nv, ph = 2 * M_PI * i / nu;
        m.V.row(1 + (j - 1) * nu + i) = Eigen::RowVector3d(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), -std::cos(th));
      }
    m.V.row(m.V.rows() - 1) = Eigen::RowVector3d(0, 0, 1);
    std::vector<Eigen::Vector3i> f;
    auto id = [&](int j, int i) { return 1 + (j - 1) * nu + (i % nu); };
    for (int i = 0; i < nu; ++i) f.emplace_back(0, id(1, i + 1), id(1, i));
    for (int j = 1; j + 1 < nv; ++j)
      for (int i = 0; i < nu; ++i) {
        f.emplace_back(id(j, i), id(j, i + 1), id(j + 1, i + 1));
        f.emplace_back(id(j, i), id(j + 1, i + 1), id(j + 1, i));
      }
    const int top = static_cast<int>(m.V.rows()) - 1;
    for (int i = 0; i < nu; ++i) f.emplace_back(top, id(nv - 1, i), id(nv - 1, i + 1));
    m.F.resize(static_cast<Eigen::Index>(f.size()), 3);
    for (size_t k = 0; k < f.size(); ++k) m.F.row(static_cast<Eigen::Index>(k)) = f[k].transpose();
    m.V *= o.radius;
  } else if (o.shape == ObstacleShape::box) {
    m.V.resize(8, 3);
    for (int k = 0; k < 8; ++k)
      m.V.row(k) = Eigen::RowVector3d((k & 1 ? 1 : -1) * o.half_extents[0], (k & 2 ? 1 : -1) * o.half_extents[1],
                                      (k & 4 ? 1 : -1) * o.half_extents[2]);
    m.F.resize(12, 3);
    m.F << 0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6, 0, 1, 5, 0, 5, 4, 2, 6, 7, 2, 7, 3, 0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5;
  } else if (o.shape == ObstacleShape::mesh) {
    if (o.mesh) m.V = o.mesh->V, m.F = o.mesh->F;  // body coordinates: the OBJ, scaled (and welded)
  } else {
    const Eigen::Vector3d n = o.normal;
    const Eigen::Vector3d a = n.unitOrthogonal(), b = n.cross(a);
    const double L = 2.0;
    m.V.resize(4, 3);
    m.V.row(0) = (-L * a - L * b).transpose();
    m.V.row(1) = (L * a - L * b).transpose();
    m.V.row(2) = (L * a + L * b).transpose();
    m.V.row(3) = (-L * a + L * b).transpose();
    m.F.resize(2, 3);
    m.F << 0, 1, 2, 0, 2, 3;
  }
  for (Eigen::Index k = 0; k < m.V.rows(); ++k)
    m.V.row(k) = o.motion.apply(o.center + Eigen::Vector3d(m.V.row(k)), t).transpose();
  return m;
}

class FrameWriter {
 public:
  FrameWriter(const Scene& scene, const fs::path& dir) : scene_(scene), dir_(dir) {
    const auto& spec = scene.spec;
    for (size_t c = 0; c < spec.cloths.size(); ++c) {
      const int f0 = scene.cloth_face_offset[c], f1 = scene.cloth_face_offset[c + 1];
      Eigen::MatrixX3i F = scene.mesh.faces().middleRows(f0, f1 - f0).array() - scene.cloth_vertex_offset[c];
      faces_.push_back(F);
    }
    names_ = cloth_output_names(spec);
    if (spec.output.vtp) pvd_.emplace((dir_ / "frames.pvd").string());
  }
  /// List frame `k`'s files already on disk (written before a resume) in the .pvd series.
  void adopt(int k, double t) {
    if (!pvd_) return;
    const auto& spec = scene_.spec;
    const auto add = [&](const std::string& base, int part) {
      if (fs::exists(dir_ / (base + ".vtp"))) pvd_->add(t, base + ".vtp", part);
    };
    for (size_t c = 0; c < faces_.size(); ++c) add(fmt::format("{}_{:04d}", names_[c], k), static_cast<int>(c));
    const int parts = static_cast<int>(faces_.size()) + (spec.rods.empty() ? 0 : 1);
    if (!spec.rods.empty()) add(fmt::format("rods_{:04d}", k), static_cast<int>(faces_.size()));
    for (size_t o = 0; o < spec.obstacles.size(); ++o) add(fmt::format("{}_{:04d}", obstacle_output_name(spec, o), k), parts + static_cast<int>(o));
  }
  /// Write frame `k` of the current state; returns the number of files written. When a
  /// file cannot be written the frame's other files are removed again (a frame is on disk
  /// whole or not at all) and the error is rethrown.
  int write(int k, const State& s) {
    written_.clear();
    try {
      return write_files(k, s);
    } catch (...) {
      std::error_code ec;
      for (const std::string& f : written_) fs::remove(f, ec);
      throw;
    }
  }

 private:
  void write_obj(const std::string& path, const Eigen::VectorXd& x, const Eigen::MatrixX3i& F, const std::string& comment = {}) {
    weft::write_obj(path, x, F, comment), written_.push_back(path);
  }
  void write_vtp(const std::string& path, const Eigen::VectorXd& x, const Eigen::MatrixX3i& F, const Eigen::VectorXd* v = nullptr) {
    weft::write_vtp(path, x, F, v), written_.push_back(path);
  }
  void write_polylines_obj(const std::string& path, const Eigen::VectorXd& x, const std::vector<int>& first, const std::string& comment) {
    weft::write_polylines_obj(path, x, first, comment), written_.push_back(path);
  }
  void write_polylines_vtp(const std::string& path, const Eigen::VectorXd& x, const std::vector<int>& first, const Eigen::VectorXd* v) {
    weft::write_polylines_vtp(path, x, first, v), written_.push_back(path);
  }
  int write_files(int k, const State& s) {
    int files = 0;
    const auto& spec = scene_.spec;
    for (size_t c = 0; c < faces_.size(); ++c) {
      const int v0 = scene_.cloth_vertex_offset[c], nv = scene_.cloth_vertex_offset[c + 1] - v0;
      const Eigen::VectorXd x = s.x.segment(3 * v0, 3 * nv), v = s.v.segment(3 * v0, 3 * nv);
      const std::string base = fmt::format("{}_{:04d}", names_[c], k);
      if (spec.output.obj) write_obj((dir_ / (base + ".obj")).string(), x, faces_[c], fmt::format("weft frame {} t={}", k, s.t)), ++files;
      if (spec.output.vtp) {
        write_vtp((dir_ / (base + ".vtp")).string(), x, faces_[c], &v), ++files;
        pvd_->add(s.t, base + ".vtp", static_cast<int>(c));
      }
    }
    const int parts = static_cast<int>(faces_.size()) + (spec.rods.empty() ? 0 : 1);
    if (!spec.rods.empty()) {  // every rod, as polylines
      const std::string base = fmt::format("rods_{:04d}", k);
      if (spec.output.obj) write_polylines_obj((dir_ / (base + ".obj")).string(), s.x, scene_.rods.first, fmt::format("weft frame {} t={}", k, s.t)), ++files;
      if (spec.output.vtp) {
        write_polylines_vtp((dir_ / (base + ".vtp")).string(), s.x, scene_.rods.first, &s.v), ++files;
        pvd_->add(s.t, base + ".vtp", static_cast<int>(faces_.size()));
      }
    }
    for (size_t o = 0; o < spec.obstacles.size(); ++o) {
      const MeshData m = obstacle_mesh(spec.obstacles[o], s.t);
      Eigen::VectorXd x(3 * m.V.rows());
      for (Eigen::Index i = 0; i < m.V.rows(); ++i) x.segment<3>(3 * i) = m.V.row(i).transpose();
      const std::string base = fmt::format("{}_{:04d}", obstacle_output_name(spec, o), k);
      if (spec.output.obj) write_obj((dir_ / (base + ".obj")).string(), x, m.F), ++files;
      if (spec.output.vtp) {
        write_vtp((dir_ / (base + ".vtp")).string(), x, m.F), ++files;
        pvd_->add(s.t, base + ".vtp", parts + static_cast<int>(o));
      }
    }
    return files;
  }

  const Scene& scene_;
  fs::path dir_;
  std::vector<std::string> written_;  ///< the files of the frame being written
  std::vector<Eigen::MatrixX3i> faces_;
  std::vector<std::string> names_;
  std::optional<PvdSeries> pvd_;
};

class Progress {
 public:
  Progress(int total_frames, int mode, bool quiet) : total_(total_frames), quiet_(quiet) {
    bar_ = mode < 0 ? isatty(STDERR_FILENO) != 0 : mode == 1;
    start_ = std::chrono::steady_clock::now();
  }
  void update(int frame, double t, int steps) {
    if (quiet_) return;
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    const double frac = total_ > 0 ? static_cast<double>(frame) / total_ : 1.0;
    const double eta = frac > 0 ? wall * (1 - frac) / frac : 0;
    if (bar_) {
      const int w = 30, filled = static_cast<int>(frac * w);
      fmt::print(stderr, "\r[{}{}] {:3.0f}% frame {}/{} t={:.3f}s {:.1f} steps/s ETA {:.0f}s ", std::string(filled, '#'),
                 std::string(w - filled, ' '), 100 * frac, frame, total_, t, steps / std::max(wall, 1e-9), eta);
      if (frame == total_) fmt::print(stderr, "\n");
    } else {
      const int decile = static_cast<int>(10 * frac);
      if (decile > last_decile_ || frame == total_) {
        last_decile_ = decile;
        fmt::print(stderr, "frame {}/{} t={:.3f}s steps={} wall={:.1f}s\n", frame, total_, t, steps, wall);
      }
    }
  }
  void finish_line() {
    if (bar_ && !quiet_) fmt::print(stderr, "\n");
  }

 private:
  int total_;
  bool quiet_, bar_ = false;
  int last_decile_ = -1;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace

int run_scene(const RunOptions& options) {
  const auto wall_start = std::chrono::steady_clock::now();
  // Under mpirun, rank 0 writes the outputs and the log; the others run silently.
  const MpiLaunch mpi = mpi_launch();
  RunOptions opt = options;
  std::optional<PrivateOutput> private_out;
  if (mpi.rank > 0) {
    private_out.emplace(mpi.rank);
    opt.out_dir = private_out->path.string();
    opt.quiet = true;
    // Its frames and statistics would be rank 0's: not written (the simulation is the same).
    for (const char* o : {"output.obj=false", "output.vtp=false", "output.stats=false"}) opt.overrides.emplace_back(o);
    spdlog::set_level(spdlog::level::off);
  }
  // 1. Validate everything before touching the output directory: the scene, the
  //    checkpoint options, and the checkpoint to resume from.
  std::unique_ptr<AnySimulator> sim;
  std::optional<Checkpoint> resumed;
  long long step0 = 0;
  try {
    sim = make_simulator(load_scene(opt.scene, opt.overrides));
    require_distributed_solver(*sim, mpi);
    if (opt.checkpoint_every < 0)
      throw ConfigError(fmt::format("--checkpoint-every {}: must be a number of frames >= 1 (0: none)", opt.checkpoint_every));
    if ((opt.checkpoint_every > 0 || !opt.resume.empty()) && !sim->checkpoint_unsupported().empty())
      throw ConfigError(fmt::format("{} {}: {}", opt.resume.empty() ? "--checkpoint-every" : "--resume",
                                    opt.resume.empty() ? std::to_string(opt.checkpoint_every) : opt.resume, sim->checkpoint_unsupported()));
    if (!opt.resume.empty()) {
      resumed = read_checkpoint(opt.resume);
      step0 = resume_step(*resumed, sim->scene(), opt.resume);
      resumed->header["step"] = step0;
      try {
        sim->restore(*resumed);
      } catch (const ConfigError& e) {
        throw ConfigError(fmt::format("--resume {}: {}", opt.resume, e.what()));
      }
    }
  } catch (const ConfigError& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return exit_config;
  } catch (const std::bad_alloc&) {
    fmt::print(stderr, "error: {}: not enough memory to build this scene and its solver (std::bad_alloc); reduce the mesh resolution "
               "or the rod count\n", opt.scene);
    return exit_config;
  }
  const Scene& scene = sim->scene();
#ifdef _OPENMP
  // Threads by size: a small scene's loops are too short to pay for waking a second thread.
  if (!opt.threads_given && sim->state().num_vertices() < parallel_min_vertices) omp_set_num_threads(1);
  // The ranks of one machine share its cores.
  else if (!opt.threads_given && mpi.size > 1) omp_set_num_threads(std::max(1, omp_get_num_procs() / mpi.size));
#endif
  const auto& time = scene.spec.time;
  const int spf = time.steps_per_frame(), frames = time.num_frames();
  const int every = scene.spec.output.every;
  const int frame0 = static_cast<int>(step0 / spf);  // the last frame the checkpoint's state completes
  const fs::path dir = opt.out_dir.empty() ? fs::path("out") : fs::path(opt.out_dir);
  std::vector<std::string> kept_stats;  // on resume: the lines of the steps before the checkpoint
  try {
    fs::create_directories(dir);
    {  // a directory that exists but cannot be written fails here, before any file is touched
      const fs::path probe = dir / ".weft-write-test";
      errno = 0;
      std::ofstream test(probe);
      if (!test) throw fs::filesystem_error("cannot create a file in it", probe, std::error_code(errno ? errno : EACCES, std::generic_category()));
      test.close();
      fs::remove(probe);
    }
    if (resumed) {
      kept_stats = clear_outputs_after(dir, frame0, step0);
    } else {
      clear_previous_outputs(dir);
    }
  } catch (const fs::filesystem_error& e) {
    fmt::print(stderr, "error: cannot prepare output directory {}: {}\n", dir.string(), e.what());
    return exit_config;
  }

  // 2. Effective scene and parameters, for reproduction.
  Json effective;
  {
    std::ifstream in(opt.scene);
    effective = Json::parse(in, nullptr, true, true);
    for (const auto& o : opt.overrides) apply_override(effective, o);
    // SA's preset auto picks its settings by size from the keys the scene gave: those stay as
    // given (every effective value would pin auto's small-mesh settings at every size).
    const Json given = effective.contains("linear") ? effective["linear"].value("preconditioner", Json::object()) : Json::object();
    const Json params = sim->params();
    for (const auto& [k, v] : params.items()) effective[k] = v;
    effective["combo"] = std::string(sim->combo());  // the one that ran (linear.solver may have swapped the solver)
    if (effective.contains("linear") && effective["linear"].contains("preconditioner") &&
        effective["linear"]["preconditioner"].value("preset", "") == "auto") {
      Json kept = given;
      kept["preset"] = "auto";
      effective["linear"]["preconditioner"] = kept;
    }
  }

  clear_stop();
  auto old_int = std::signal(SIGINT, on_signal);
  auto old_term = std::signal(SIGTERM, on_signal);

  int files = 0, frames_written = 0, steps = 0;
  std::optional<ContactAudit> audit;  // cloth runs: the exact checks at every frame
  if (scene.spec.rods.empty() && scene.mesh.num_faces() > 0) {
    audit.emplace();
    audit->check(scene, sim->state());
  }
  long newton_total = 0, linear_total = 0;
  int newton_max = 0;
  int subdivided = 0, deepest_subdivision = 0;  // steps retried as substeps (time.max_subdivisions)
  StageTimes stage_total;
  std::string status = "completed";
  Json failure;
  int code = exit_ok;
  const long long total = time.num_steps();
  // A file that cannot be written (a full disk, a directory made read-only): the run stops
  // with exit 3; the frames and statistics lines written before it stay complete.
  const auto output_failed = [&](const std::exception& e, long long after_step) {
    status = "failed";
    failure = {{"stage", "output"}, {"status", "output_error"}, {"after_step", after_step}, {"time", sim->state().t}, {"reason", e.what()}};
    code = exit_failed;
    fmt::print(stderr, "\nerror: writing the output after step {} failed: {}; the frames and statistics written before are intact\n",
               after_step, e.what());
  };
  const auto save = [&](const Checkpoint& c, const char* name) {
    Checkpoint k = c;
    k.header["run"] = {{"scene", opt.scene}, {"overrides", opt.overrides}, {"lapack", linear::lapack_library()}, {"build", build_commit()}};
    write_checkpoint((dir / name).string(), k);
    return std::string(name);
  };
  // The simulator's state as a checkpoint of the start of step s (the simulator counted a
  // failed or interrupted step, and put its state back to the step's start); none when the
  // clock moved, i.e. the state is not that start.
  const bool checkpoints = sim->checkpoint_unsupported().empty();
  const auto start_of = [&](long long s) {
    std::optional<Checkpoint> c;
    if (!checkpoints) return c;
    c = sim->checkpoint();
    c->header["step"] = s - 1;
    if (std::abs(c->header["time"].get<double>() - static_cast<double>(s - 1) * time.dt) > 1e-9 * std::max(1.0, static_cast<double>(s)) * time.dt)
      c.reset();
    return c;
  };

  std::optional<FrameWriter> writer;
  std::optional<StatsWriter> stats;
  Progress progress(frames - frame0, opt.progress, opt.quiet);
  try {
    write_json_file((dir / "scene.json").string(), effective);
    writer.emplace(scene, dir);
    if (scene.spec.output.stats) {
      stats.emplace((dir / "stats.jsonl").string());
      for (const auto& line : kept_stats) stats->write_line(line);
    }
    for (int k = 0; k < frame0; ++k) writer->adopt(k, time.frame_time(k));  // resumed: frames on disk stay in the .pvd
    if (step0 % spf == 0)
      files += writer->write(frame0, sim->state()), ++frames_written;
    else
      writer->adopt(frame0, time.frame_time(frame0));
  } catch (const std::exception& e) {
    output_failed(e, step0);
  }

  if (!opt.quiet && code == exit_ok) {
    if (scene.spec.rods.empty())
      spdlog::info("{}: {} vertices, {} faces, {} hinges; combo {}; dt = {} s, {} steps/frame, {} frames", opt.scene,
                   scene.mesh.num_vertices(), scene.mesh.num_faces(), scene.mesh.num_hinges(), sim->combo(), time.dt, spf, frames);
    else
      spdlog::info("{}: {} rods, {} vertices; combo {}; dt = {} s, {} steps/frame, {} frames", opt.scene, scene.rods.num_rods(),
                   scene.rods.num_vertices(), sim->combo(), time.dt, spf, frames);
    if (resumed)
      spdlog::info("resumed from {} at step {} (t = {} s), written by combo {}", opt.resume, step0, sim->state().t,
                   resumed->header.value("combo", "?"));
  }
  if (resumed && resumed->header.contains("resume_caveats") && resumed->header["resume_caveats"].is_array())
    for (const Json& why : resumed->header["resume_caveats"])  // the run goes on, but not to the bit
      spdlog::warn("the resumed run will not repeat the uninterrupted one to the bit: {}", why.is_string() ? why.get<std::string>() : why.dump());

  const auto signal_name = [](int sig) { return sig == SIGINT ? std::string("SIGINT") : sig == SIGTERM ? std::string("SIGTERM") : std::to_string(sig); };
  // A signal, between two steps or inside one (the step then stopped and put its state
  // back to its start): the state at the start of step s is kept in checkpoint.wckp.
  // `inside`: the signal stopped step s (the simulator counted it); else it came before it.
  const auto interrupt = [&](long long s, int sig, bool inside) {
    status = "interrupted";
    failure = {{"signal", signal_name(sig)}, {"after_step", s - 1}, {"time", sim->state().t}};
    code = 128 + sig;
    try {
      std::optional<Checkpoint> c = inside ? start_of(s) : checkpoints ? std::optional<Checkpoint>(sim->checkpoint()) : std::nullopt;
      if (c) failure["checkpoint"] = save(*c, "checkpoint.wckp");
    } catch (const std::exception& e) {
      failure["checkpoint_error"] = e.what();
      fmt::print(stderr, "\nerror: the checkpoint could not be written: {}\n", e.what());
    }
  };
  for (long long s = step0 + 1; code == exit_ok && s <= total; ++s) {
    if (const int sig = stop_requested()) {  // between two steps: the state is that of step s - 1's end
      interrupt(s, sig, false);
      break;
    }
    StepReport rep;
    try {
      rep = sim->step();
    } catch (const std::exception& e) {
      // The simulators report their own internal errors as failed steps; this catches what
      // escapes a wrapper. The state may then be anywhere: start_of() checks the clock.
      rep.step = static_cast<int>(s);
      rep.time = sim->state().t + time.dt;
      rep.dt = time.dt;
      rep.status = Status::numerical_issue;
      rep.failed_stage = "internal";
      rep.message = fmt::format("internal error: {}", e.what());
    }
    if (rep.status == Status::interrupted) {
      interrupt(s, std::max(1, stop_requested()), true);
      break;
    }
    if (rep.ok() && !std::isfinite(rep.newton.final_residual))
      rep.fail("integrator", Status::numerical_issue, "the step ended with a non-finite residual", rep.time - rep.dt);
    ++steps;
    newton_total += rep.newton.iterations;
    newton_max = std::max(newton_max, rep.newton.iterations);
    if (rep.ok() && rep.substeps > 1) {
      ++subdivided;
      deepest_subdivision = std::max(deepest_subdivision, rep.subdivisions);
    }
    linear_total += rep.linear.iterations;
    try {
      ScopedTimer t(rep.times, Stage::output);
      if (stats) stats->write(to_json(rep));
    } catch (const std::exception& e) {
      output_failed(e, rep.ok() ? s : s - 1);
    }
    stage_total += rep.times;
    if (!rep.ok()) {
      status = "failed";
      failure = {{"step", rep.step}, {"time", rep.time}, {"stage", rep.failed_stage},
                 {"status", to_string(rep.status)}, {"reason", rep.message}};
      // A failed step leaves the state at its start (the simulators restore it, internal
      // errors included), so the step replays from a checkpoint of it.
      std::optional<Checkpoint> before = start_of(s);
      try {
        if (before) failure["checkpoint"] = save(*before, "failed_step.wckp");
      } catch (const std::exception& e) {
        before.reset();
        failure["checkpoint_error"] = e.what();
      }
      progress.finish_line();
      fmt::print(stderr, "error: step {} (t = {} s) failed in stage '{}': {}: {}\n", rep.step, rep.time, rep.failed_stage,
                 to_string(rep.status), rep.message);
      if (before) {
        std::string command = "weft run " + opt.scene;
        for (const auto& o : opt.overrides) command += " " + o;
        const std::string file = (dir / "failed_step.wckp").string();
        fmt::print(stderr, "the state at the start of step {} is in {}; `{} --resume {} -o OTHER_DIR` replays it\n", rep.step, file, command, file);
      } else if (failure.contains("checkpoint_error")) {
        fmt::print(stderr, "the state at the start of step {} could not be saved: {}\n", rep.step, failure["checkpoint_error"].get<std::string>());
      } else if (!checkpoints) {
        fmt::print(stderr, "this combination does not write checkpoints ({}): no replay file\n", sim->checkpoint_unsupported());
      }
      code = exit_failed;
      break;
    }
    if (code != exit_ok) break;  // the statistics could not be written
    if (s % spf != 0 && s != total) continue;
    const int f = static_cast<int>((s + spf - 1) / spf);  // the last frame may be shorter
    if (audit) audit->check(scene, sim->state());
    try {
      if (f % every == 0 || f == frames) {
        ScopedTimer t(stage_total, Stage::output);
        files += writer->write(f, sim->state());
        ++frames_written;
      }
      if (opt.checkpoint_every > 0 && (f % opt.checkpoint_every == 0 || f == frames)) {
        ScopedTimer t(stage_total, Stage::output);
        save(sim->checkpoint(), "checkpoint.wckp");
      }
    } catch (const std::exception& e) {
      output_failed(e, s);
      break;
    }
    progress.update(f - frame0, sim->state().t, steps);
  }
  std::signal(SIGINT, old_int);
  std::signal(SIGTERM, old_term);
  if (status == "interrupted") {
    progress.finish_line();
    fmt::print(stderr, "interrupted by {} after {} steps; output up to t = {} s is intact{}\n", failure["signal"].get<std::string>(),
               step0 + steps, sim->state().t,
               failure.contains("checkpoint") ? fmt::format("; `--resume {}` continues", (dir / "checkpoint.wckp").string()) : std::string());
  }
  // Success means the time asked for was simulated (a guard: the loop above runs to it).
  if (code == exit_ok && std::abs(sim->state().t - time.duration) > 1e-6 * time.duration) {
    status = "failed";
    failure = {{"stage", "internal"}, {"reason", fmt::format("the run ended at t = {} s, not at time.duration = {} s", sim->state().t, time.duration)}};
    code = exit_failed;
    fmt::print(stderr, "error: {}\n", failure["reason"].get<std::string>());
  }

  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  const EnergyReport e = sim->energies();
  Json energies{{"kinetic", e.kinetic}, {"potential", e.potential}};
  for (const auto& [n, v] : e.terms) energies[n] = v;
  Json summary{{"status", status},
               {"scene", opt.scene},
               {"combo", std::string(sim->combo())},
               {"vertices", scene.spec.rods.empty() ? scene.mesh.num_vertices() : scene.rods.num_vertices()},
               {"rods", scene.rods.num_rods()},
               {"faces", scene.mesh.num_faces()},
               {"dt", time.dt},
               {"steps", step0 + steps},
               {"steps_planned", total},
               {"frames_written", frames_written},
               {"files_written", files},
               {"simulated_time", sim->state().t},
               {"wall_seconds", wall},
               {"seconds_per_step", steps ? stage_total.total() / steps : 0.0},
               {"newton_iterations", {{"total", newton_total}, {"mean", steps ? double(newton_total) / steps : 0.0}, {"max", newton_max}}},
               {"linear_iterations", {{"total", linear_total}, {"mean_per_step", steps ? double(linear_total) / steps : 0.0}}},
               {"subdivided_steps", {{"count", subdivided}, {"deepest", deepest_subdivision}}},
               {"stage_seconds", to_json(stage_total)},
               {"final_energy", energies},
               {"lapack", linear::lapack_library()},
               {"build", build_commit()},
               {"ranks", mpi.size},
               {"threads",
#ifdef _OPENMP
                omp_get_max_threads()
#else
                1
#endif
               }};
  if (audit) summary["contact_check"] = audit->to_json();
  if (!failure.is_null()) summary["failure"] = failure;
  if (resumed)
    summary["resumed_from"] = {{"checkpoint", opt.resume}, {"step", step0}, {"time", resumed->header["time"]},
                               {"combo", resumed->header.value("combo", "?")}, {"steps_run", steps}};
  try {
    write_json_file((dir / "summary.json").string(), summary);
  } catch (const std::exception& ex) {
    fmt::print(stderr, "error: the summary could not be written: {}\n", ex.what());
    if (code == exit_ok) code = exit_failed;
  }
  if (audit && !opt.quiet) {
    if (audit->clean()) spdlog::info("{}", audit->line());
    else spdlog::warn("{}", audit->line());
  }
  if (!opt.quiet && code == exit_ok)
    spdlog::info("done: {} steps in {:.2f} s ({:.2f} ms/step), Newton {:.2f}/step (max {}){}, output in {}", steps, wall,
                 1e3 * stage_total.total() / std::max(steps, 1), double(newton_total) / std::max(steps, 1), newton_max,
                 subdivided ? fmt::format(", {} steps retried as substeps (down to dt/{})", subdivided, 1 << deepest_subdivision) : std::string(),
                 dir.string());
  return code;
}

}  // namespace weft::app
