#pragma once
/// \file sa_amg.hpp
/// `SaAmg`: smoothed aggregation multigrid for cloth (methods/multigrid §4-6; Tamstorf, Jones &
/// McCormick 2015), used as a fixed SPD preconditioner (one V(1,1) cycle, zero initial
/// guess) of PCG on the prefiltered system Ahat = S A S + Sigma (I - S).
///
/// Setup per level (methods/multigrid §4.10), fine level with 3x3 blocks, coarse levels 6x6:
///   Dinv   <- block-diagonal inverse of A_l
///   lambda <- 10 steps of generalised Lanczos on A q = lambda D q, inflated (§4.7)
///   Csoc   <- mu_ij = rho(A_ii^-1/2 A_ij A_jj^-1/2) > theta max_k mu_ik, symmetrised (§4.3)
///   special<- no strong neighbour, or sum_j mu_ij < tau_dd (§4.4); their rows of P are empty
///   aggs   <- two-pass greedy aggregation, serial and deterministic (§4.5)
///   Phat,Kc<- local thin QR of the near null space K (6 rigid-body modes K <- S K on the
///             fine level), rank revealing: dropped columns stay as zero "dummy" coarse dofs (§4.6)
///   P      <- (I - omega D^-1 A_f) Phat, omega = 4 / (3 lambda), A_f = A with weak blocks
///             lumped into the diagonal (§4.8)
///   A_c    <- P^T A P (fused row-wise product, cached symbolic pattern); dummy dofs get the
///             mean diagonal of A_c (§4.9)
/// until n_l <= coarse_size nodes, coarsening stalls (n_{l+1} > stall_ratio n_l) or
/// max_levels; the coarsest level is solved by dense Cholesky (LDL^T fallback).
///
/// Smoother (§5.2): degree-k Chebyshev on D^-1 A over [lower, upper] * lambda, the same
/// polynomial before and after the coarse correction, so that B is symmetric (Appendix A);
/// it is positive definite while lambda_max(D^-1 A) < (lower + upper) * lambda.
/// With cycle_gamma = 2 the first cycle_gamma_levels coarse levels are corrected by two
/// cycles from them (B_c = 2 V_c - V_c A_c V_c: symmetric, and SPD as V_c is a convergent
/// SPD iteration).
///
/// The implementation follows the setup: linear/sa_strength.cpp (Csoc, special nodes),
/// sa_aggregation.cpp and sa_ordering.cpp (aggregates, sheets, numbering),
/// sa_prolongator.cpp (K, Phat, lambda, P), sa_amg.cpp (the hierarchy, A_c, the coarsest
/// factorisation) and sa_cycle.cpp (the smoother and the cycle).
#include <Eigen/Cholesky>
#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "framework/block_csr.hpp"
#include "framework/concepts.hpp"
#include "framework/constraints.hpp"
#include "framework/params.hpp"
#include "framework/status.hpp"
#include "linear/bsr.hpp"
#include "linear/preconditioner.hpp"

namespace weft::linear {

/// How mu_ij measures the scaled block M = A_ii^-1/2 A_ij A_jj^-1/2 (methods/multigrid §4.3).
enum class SocMeasure {
  spectral,   ///< rho(M), the thesis's measure (3x3: exact, closed-form cubic; 6x6: ||M^64||_F^(1/64), within ~2%)
  two_norm,   ///< ||M||_2 >= rho(M)
  frobenius,  ///< ||M||_F, cheapest
};
inline constexpr std::array<std::string_view, 3> soc_measure_names = {"spectral", "two_norm", "frobenius"};

/// How the aggregates of a level are numbered, which is the row order of the next level.
enum class AggregateOrder {
  natural,  ///< in the order of their seeds (or first node after `split_sheets`)
  rcm,      ///< reverse Cuthill-McKee of the aggregate graph (`sa::order_aggregates`)
  automatic,  ///< rcm where it halves the mean number distance of coupled aggregates, else natural
};
inline constexpr std::array<std::string_view, 3> aggregate_order_names = {"natural", "rcm", "auto"};

/// What a `setup` with an unchanged pattern may keep from the previous one (methods/multigrid §13).
enum class SaReuse {
  none,        ///< rebuild everything (the thesis)
  aggregates,  ///< keep strength, special nodes, aggregates and every pattern (P, P^T index,
               ///< A_c); recompute Dinv, lambda, K (positions and S), QR, P and A_c values and
               ///< the coarse factorisation
  frozen,      ///< keep the whole hierarchy (a private copy of the fine matrix included) until
               ///< `analyze_pattern`: B stays a fixed SPD map, only its quality drops
  step,        ///< `aggregates` at the first setup of each time step (`begin_step`); the step's
               ///< other setups keep the coarse levels and the fine level's Lanczos bound and
               ///< smooth with the current fine matrix: one refresh per step, not per Newton
               ///< iteration, and no copy of the fine matrix
};
inline constexpr std::array<std::string_view, 4> sa_reuse_names = {"none", "aggregates", "frozen", "step"};

/// Named settings of `SaAmg::Params` (the key `preset`, read before the others: keys given
/// beside it change single settings of the preset). docs/linear-solvers.md gives the
/// measurements behind each.
enum class SaPreset {
  automatic,  ///< `thesis` with reuse = step below `large_from` fine rows, `large` from there
  thesis,     ///< the thesis' V(1,1) hierarchy rebuilt at every setup: reproduces Table 11.1
  large,      ///< iterations bounded from 10k to 1M vertices and on stacked sheets, at a dearer setup
};
inline constexpr std::array<std::string_view, 3> sa_preset_names = {"auto", "thesis", "large"};

/// How the prolongators' values are stored (products always accumulate in double). P is
/// rounded to the storage before the Galerkin product, so A_c = P^T A P holds exactly for the
/// stored P and the cycle stays SPD whatever the storage.
enum class ValueStorage {
  double_precision,  ///< 8 bytes per value
  fixed16,           ///< 2 bytes per value: P = Q diag(s), Q in int16 and one double scale per
                     ///< coarse dof (column of P), s_c = max_i |P_ic| / 32767: an absolute error
                     ///< of at most 1.5e-5 of the column's largest entry
};
inline constexpr std::array<std::string_view, 2> value_storage_names = {"double", "fixed16"};

/// Which upper estimate of lambda_max(D^-1 A) the smoother and omega use (methods/multigrid §4.7).
enum class LambdaBound {
  ritz_residual,  ///< largest Ritz value + its residual bound |beta_m s_m|
  ritz_factor,    ///< 1.1 * largest Ritz value
  ritz,           ///< the Ritz value itself: an underestimate (only for negative controls)
};
inline constexpr std::array<std::string_view, 3> lambda_bound_names = {"ritz_residual", "ritz_factor", "ritz"};

/// Near-null-space vectors: #dofs by 6, row-major (node i's block is rows B i .. B i + B - 1).
using NullSpace = Eigen::Matrix<double, Eigen::Dynamic, 6, Eigen::RowMajor>;

/// One level of the hierarchy, as reported by `SaAmg::stats()`.
struct SaLevelStats {
  int rows = 0;                ///< block rows (nodes)
  int block_size = 0;          ///< 3 (fine) or 6
  long long nnz_blocks = 0;    ///< stored blocks of A_l
  int special = 0;             ///< special nodes (no interpolation)
  int aggregates = 0;          ///< = rows of the next level (0 on the coarsest)
  int deficient = 0;           ///< aggregates whose local QR dropped a column
  int sheet_splits = 0;        ///< aggregates added by `split_sheets`
  int sheet_merges = 0;        ///< small pieces joined to a neighbour by `split_merge`
  bool reordered = false;      ///< aggregates renumbered by RCM (`aggregate_order`)
  int max_aggregate = 0;       ///< largest aggregate (nodes)
  long long nnz_p = 0;         ///< stored blocks of P_l
  int restriction_chunks = 0;  ///< row chunks of the parallel restriction P_l^T r (0: coarsest)
  double ritz = 0;             ///< largest Lanczos Ritz value of D^-1 A_l
  double lambda = 0;           ///< the inflated bound used
  double mode_correction = 0;  ///< largest relative change of a row of P by `preserve_modes` (0: off or exact)
  long long truncated = 0;     ///< blocks of P_l dropped by `prolongator_truncation`
};

/// Setup wall time split [s] (summed over levels).
struct SaSetupTimes {
  double strength = 0, aggregation = 0, qr = 0, smoothing = 0, galerkin = 0, lanczos = 0;
  double other = 0;  ///< near null space, block inverses, coarse factorisation, bookkeeping
  double total = 0;
};

struct SaStats {
  std::vector<SaLevelStats> levels;
  SaSetupTimes times;
  bool reused = false;        ///< the last setup reused structure (reuse != none)
  bool coarse_direct = true;  ///< the coarsest level is solved exactly (else: smoother only)
  std::string message;        ///< why the last setup failed ("" on success)
};

/// Building blocks of the setup, exposed for tests (instantiated for B = 3 and 6).
namespace sa {

/// mu_ij of every stored block (0 on the diagonal) and the symmetrised strong flags:
/// strong[k] = 1 iff mu_ij > theta max_k mu_ik or mu_ji > theta max_k mu_jk (i != j).
/// The couplings along which a level's nodes form sheets, as (i, j) pairs with i < j.
using SheetEdges = std::vector<std::pair<int, int>>;
template <int B>
void strength(const BsrView<B, B>& A, double theta, SocMeasure measure, std::vector<double>& mu,
              std::vector<std::uint8_t>& strong, const SheetEdges* sheets = nullptr);
/// The symmetrised strong flags of `strength` from given mu: strong[k] = 1 iff mu_ij > theta
/// max_k mu_ik or mu_ji > theta max_k mu_jk (i != j). With `sheets` (sorted), the maximum
/// runs over the row's couplings within its sheets only, so that springs much stiffer than
/// the sheet do not make its own couplings weak (`SaAmg::Params::sheet_strength`); a row
/// without such a coupling keeps the maximum over all.
template <int B>
void strong_flags(const BsrView<B, B>& A, const std::vector<double>& mu, double theta, std::vector<std::uint8_t>& strong,
                  const SheetEdges* sheets = nullptr);
/// mu of one scaled block M = A_ii^-1/2 A_ij A_jj^-1/2 under `measure` (B = 3 or 6).
template <int B>
double measure(const Eigen::Matrix<double, B, B>& M, SocMeasure measure);
/// Spectral radius of a general 3x3 matrix (roots of the characteristic cubic).
double spectral_radius3(const Eigen::Matrix3d& M);

/// Clears every flag of a block of A that touches a special node.
template <int B>
void weaken_special(const BsrView<B, B>& A, const std::vector<std::uint8_t>& special, std::vector<std::uint8_t>& flags);

/// Marks special nodes (no strong neighbour, or sum_j mu_ij < tau_dd) and clears every strong
/// flag that touches one (repeated until no new node loses its last strong neighbour).
/// Returns the number of special nodes.
template <int B>
int special_nodes(const BsrView<B, B>& A, const std::vector<double>& mu, double tau_dd, std::vector<std::uint8_t>& strong,
                  std::vector<std::uint8_t>& special);

/// Node -> aggregate map (-1 for special nodes) of the two-pass aggregation (methods/multigrid §4.5).
struct Aggregates {
  std::vector<int> node_agg;
  int count = 0;
  int max_size = 0;
};
/// Pass 1 visits the nodes in the order `scan` (empty: by index); under
/// `AggregateOrder::rcm` that is the natural numbering of the level above, so the aggregates
/// do not depend on the renumbering.
template <int B>
Aggregates aggregate(const BsrView<B, B>& A, const std::vector<std::uint8_t>& strong,
                     const std::vector<std::uint8_t>& special, const std::vector<int>& scan = {});

/// Renumbers the aggregates by reverse Cuthill-McKee (Boost.Graph) of the graph in which two
/// aggregates are adjacent when A couples two of their members. The numbering is the row
/// order of the next level's operator and the column order of P: coupled aggregates get
/// nearby numbers, so the coarse products read the blocks and vector entries of nearby rows
/// instead of jumping across the matrix. Deterministic. With `automatic` the new numbering
/// is kept only when it at least halves the mean |a - b| over coupled aggregates a, b: a
/// sheet's natural numbering follows its rows and is already as local as RCM's, while the
/// springs between the layers of a folded sheet join aggregates numbered far apart (mean
/// distance 1057 naturally and 96 by RCM on the first level of dropVertical at 160k). Returns
/// the new number of each aggregate, or nothing when the natural numbering stays.
template <int B>
std::vector<int> order_aggregates(const BsrView<B, B>& A, Aggregates& aggs, AggregateOrder mode);

/// A 3x3 coupling block counts as rank-one when ||adj M||_F <= this * ||M||_F^2 (the ratio
/// is about sigma_2 / sigma_1 once sigma_3 << sigma_2): a spring k n n^T gives round-off,
/// a membrane block order one.
inline constexpr double rank_one_tolerance = 1e-6;
/// The fine level's sheet couplings: the off-diagonal blocks that are not rank-one.
SheetEdges sheet_edges(const BsrView<3, 3>& A);
/// Splits every aggregate into its sheets, the connected components of its members under
/// `edges` (`SaAmg::Params::split_sheets`). Aggregates are renumbered in the order their
/// first node comes in `scan` (empty: by index; see `aggregate`). Returns how many
/// aggregates it added.
/// With `A` and `bonded` > 0 (fine level, `SaAmg::Params::split_bonded`): an aggregate whose
/// couplings between its pieces, summed as -A_ij (k n n^T for springs), have a middle
/// eigenvalue above `bonded` times the largest stays whole: its layers are bonded in shear
/// and cannot slide apart.
int split_sheets(const SheetEdges& edges, Aggregates& aggs, const std::vector<int>& scan = {},
                 const BsrView<3, 3>* A = nullptr, double bonded = 0);
/// Joins each aggregate of at most `max_size` nodes to the larger aggregate (more than
/// `max_size` nodes) it shares the most `edges` with, the lowest-numbered on a tie
/// (`SaAmg::Params::split_merge`); an aggregate with no such neighbour stays. The others
/// keep their relative order. Sheet edges join nodes of one sheet, so a piece the split cut
/// off its layer's neighbours rejoins one of them. Returns how many aggregates it removed.
int merge_small_aggregates(const SheetEdges& edges, Aggregates& aggs, int max_size);
/// The next level's sheet couplings: aggregates a != b are coupled when two of their members
/// are (sorted, without duplicates).
SheetEdges coarse_sheet_edges(const SheetEdges& edges, const Aggregates& aggs);

/// The six rigid-body modes at `positions` (3 per vertex, centred on their mean), filtered
/// K <- S K when `constraints` is given (methods/multigrid §4.2).
NullSpace rigid_body_modes(const Eigen::VectorXd& positions, const ConstraintSet* constraints);

/// Tentative prolongator: Phat = blockdiag(Q_a) stored as one B x 6 block per node (zero for
/// special nodes), Kc = [R_1; ...; R_n2] (methods/multigrid §4.6).
struct Tentative {
  std::vector<double> Q;              ///< #nodes blocks of B x 6 (row-major)
  NullSpace Kc;                       ///< 6 #aggregates by 6
  std::vector<std::uint8_t> dummy;    ///< per coarse dof: its column was dropped
  int deficient = 0;                  ///< aggregates with a dropped column
};
template <int B>
Tentative tentative_prolongator(const Aggregates& aggs, const NullSpace& K, double tolerance);

/// Largest Ritz value of A q = lambda D q after `steps` generalised Lanczos steps from a
/// fixed pseudo-random start, and its residual bound |beta_m s_m|.
struct LanczosResult {
  double ritz = 0;
  double residual = 0;
  int steps = 0;
};
template <int B>
LanczosResult lanczos(const BsrView<B, B>& A, const std::vector<double>& Dinv, int steps);

/// Pattern of P = (I - omega D^-1 A_f) Phat: row i (non-special) holds the aggregates of i
/// and of its neighbours (strong neighbours only when `strong` is given); special rows are empty.
template <int B>
BlockMatrix<B, 6> prolongator_pattern(const BsrView<B, B>& A, const std::vector<std::uint8_t>* strong,
                                      const Aggregates& aggs);
/// Values of P for a pattern from `prolongator_pattern` with the same `strong`. With
/// `strong`, A_f keeps the strong blocks and lumps the weak ones into the diagonal block.
template <int B>
void prolongator_values(const BsrView<B, B>& A, const std::vector<double>& Dinv, const std::vector<std::uint8_t>* strong,
                        const Aggregates& aggs, const Tentative& t, double omega, BlockMatrix<B, 6>& P);

/// One more damped Jacobi step of a prolongator: Z (I - omega D^-1 A_f) P, with A_f = A whose
/// weak blocks (strong[k] == 0) are lumped into the diagonal (strong == nullptr: A_f = A) and
/// Z zeroing the rows of nodes outside every aggregate. Its pattern is the union of P's rows
/// over A_f's graph.
template <int B>
BlockMatrix<B, 6> smooth_prolongator(const BsrView<B, B>& A, const std::vector<double>& Dinv,
                                     const std::vector<std::uint8_t>* strong, const Aggregates& aggs, double omega,
                                     const BlockMatrix<B, 6>& P);

/// Correct P row by row so that it maps the coarse near null space Kc to the smoothed fine
/// one, P Kc = (Z (I - omega D^-1 A))^degree K with the whole A: the change of each row is
/// the least-norm one within its pattern, X (Kc_r^T Kc_r)^+ Kc_r^T with Kc_r the rows of Kc
/// on the row's columns (the constraint step of energy-minimising prolongators, Olson,
/// Schroder and Tuminaro 2011). The filter A_f lumps a weak block into the diagonal, which
/// keeps the translations (A_f 1 = A 1) and loses the rotations (A_f K_rot != A K_rot): on a
/// bending-dominated sheet the smoothed rotation modes then lose the linear out-of-plane
/// fields the coarse space needs. Returns the largest relative correction max_i |X_i| /
/// |target_i| (0: the constraint held already).
template <int B>
double preserve_modes(const BsrView<B, B>& A, const std::vector<double>& Dinv, const Aggregates& aggs, double omega,
                      int degree, const NullSpace& K, const NullSpace& Kc, BlockMatrix<B, 6>& P);

/// Zeroes and removes the blocks of each row of P whose Frobenius norm is below `fraction`
/// times the row's largest; returns how many. A row keeps at least its largest block.
template <int B>
long long truncate_prolongator(BlockMatrix<B, 6>& P, double fraction);

/// Row chunks [b_k, b_{k+1}) of P (at least `min_rows` rows each but the last) such that the
/// rows holding a block of any column J fall in two consecutive chunks at most: chunks of
/// one parity then share no column, and P^T r is a lock-free parallel scatter whose sums do
/// not depend on the thread count (the cycle's restriction). With first(J) and last(J) the
/// first and last rows of column J, b_{k+1} = max(b_k + min_rows, 1 + max{last(J) : first(J)
/// < b_k}): a column starting in chunk k ends before b_{k+2}. A badly ordered mesh gives few,
/// long chunks (less parallelism), never a wrong sum.
template <int B>
std::vector<int> restriction_chunks(const BsrView<B, 6>& P, int min_rows = 512);

}  // namespace sa

/// Smoothed aggregation multigrid V(1,1) preconditioner (methods/multigrid §4-6). `apply` is const
/// but uses per-level work vectors: one `apply` at a time per object.
class SaAmg {
 public:
  static constexpr std::string_view name = "sa";
  struct Params {
    /// The named settings these start from (see `SaPreset`). The member initialisers below
    /// are `auto`'s settings below `large_from`; `of` gives every preset's.
    SaPreset preset = SaPreset::automatic;
    /// With preset = auto: the fine rows (vertices) from which the hierarchy takes the
    /// `large` settings. On the hanging cloth with reuse = aggregates, `large` is 1.09x the
    /// thesis' hierarchy per step at 40k vertices and 1.01x at 161k (its setup costs more
    /// than its fewer iterations save); on the linear benchmarks it wins from 361k, and its
    /// iterations stay within 2x from 10k to 1M where the thesis' grow 3.4-4.3x.
    int large_from = 160000;
    /// Strength threshold relative to the row maximum (methods/multigrid §4.3, the thesis' 0.48): block
    /// (i, j) is strong if mu_ij > theta max_k mu_ik. The prolongator is smoothed with the
    /// filtered matrix A_f of the strong blocks (weak ones lumped into the diagonal).
    double theta = 0.48;
    /// Threshold, relative to the row maximum as theta, of the couplings aggregation follows
    /// and special-node detection counts; 0: theta itself (the thesis aggregates along
    /// theta's strong blocks). 0.25 merges about 9 nodes per aggregate instead of 6 on the
    /// sheets: smaller coarse levels, which let degree-2 prolongators and the W-cycle fit in
    /// 1.5x Diag-PCG's memory (bench/results/table-11-1/M4-aggregation-theta.md). The `large`
    /// preset's.
    double aggregation_theta = 0;
    SocMeasure strength = SocMeasure::spectral;
    double diagonal_dominance = 1e-2;  ///< tau_dd: special if sum_j mu_ij < tau_dd
    int coarse_size = 50;             ///< stop coarsening at <= this many nodes
    int max_levels = 10;
    double stall_ratio = 0.8;          ///< stop when n_{l+1} > stall_ratio n_l
    int dense_limit = 4000;            ///< largest coarsest level (dofs) solved densely; above: smoother only
    double qr_tolerance = 1e-10;       ///< relative drop tolerance of the rank-revealing local QR
    int lanczos_steps = 10;
    LambdaBound lambda_bound = LambdaBound::ritz_residual;
    int chebyshev_degree = 2;
    double chebyshev_lower = 0.1;      ///< a / lambda
    double chebyshev_upper = 1.1;      ///< b / lambda
    /// Coarse cycles per visit of levels 1 .. cycle_gamma_levels (gamma of the mu-cycle): 1 is
    /// the V-cycle; 2 makes the correction of such a level two V-cycles from it (a W-cycle
    /// there, B_l = 2 V_l - V_l A_l V_l, still SPD). methods/multigrid §2.4: W-cycles converge under the
    /// weak approximation property alone, which one-step smoothed rigid-mode aggregates of a
    /// bending-dominated sheet keep while the V-cycle degrades with depth. The extra cycles
    /// run in place, with no vectors of their own.
    int cycle_gamma = 1;
    int cycle_gamma_levels = 1;        ///< how many coarse levels (from level 1) get cycle_gamma
    /// Damped Jacobi steps of the prolongator smoother, P = (Z (I - omega D^-1 A_f))^degree Phat,
    /// on the first prolongator_degree_levels levels (from the fine one). The sheets' bending
    /// makes the operator biharmonic-like, and one step leaves coarse basis functions whose
    /// energy grows with the resolution: the iterations grow with the size
    /// (bench/results/table-11-1/I2-prolongator-degree.md). Two steps on levels 0 and 1 keep
    /// them flat, at a wider P and denser coarse operators (more memory and setup).
    int prolongator_degree = 1;
    int prolongator_degree_levels = 2;
    /// Drop from each row of a smoothed prolongator the blocks whose Frobenius norm is below
    /// this fraction of the row's largest (0: keep all), before the Galerkin product. Each
    /// smoothing step widens P by A's stencil, and the coarse operator's fill grows with P's
    /// width; the dropped blocks carry a small share of the row. `preserve_modes` (required)
    /// then corrects the kept blocks so that P still maps the coarse near null space to the
    /// fine one smoothed with the whole A (the truncation-and-repair of classical AMG's
    /// interpolation, Stuben 2001, with SA's rigid modes in place of the constant).
    double prolongator_truncation = 0;
    /// What a setup with an unchanged pattern keeps (see `SaReuse`). Keeping the aggregates
    /// and patterns between Newton iterations and steps halved the SA setup of the hanging
    /// cloth at 40k vertices (2.82 -> 2.30 s per step) at the same iterations. Refreshing the
    /// values once per time step (`step`, the default) cuts the setup further, from 36 % to
    /// 13-14 % of the linear time, for 19 % more PCG iterations: 0.89-0.92x the time per
    /// step of `aggregates` there, 0.98x on the eight-sheet stack (bench/results/linear-choice,
    /// "Refreshing once per step").
    SaReuse reuse = SaReuse::step;
    /// Storage of the prolongators' values (see `ValueStorage`). fixed16 left SA+PPCG's
    /// iterations unchanged on every example at 10k-361k (and 1M pinned) at a quarter of P's
    /// value bytes (bench/results/table-11-1/M-memory.md, M3-fixed16.md).
    ValueStorage prolongator_storage = ValueStorage::fixed16;
    /// Store the coarse operators A_l (l >= 1) in single precision: each block is formed in
    /// double by the Galerkin product and rounded once; smoothing, the next level's Galerkin
    /// product and the coarsest factorisation read the rounded, still exactly symmetric A_l.
    /// A_1 is SA's largest array (bench/results/table-11-1/M-memory.md).
    bool single_coarse_operators = true;
    /// Keep the smoother's block inverses D_l^-1 in single precision once the level is built
    /// (the Lanczos bound and the prolongator smoothing use them in double first).
    bool single_block_inverses = true;
    /// The fine level's smoother solves with each diagonal block of A (read through the
    /// filters, as the setup read it) when it needs D_i^-1, instead of keeping n inverses
    /// (36 bytes per vertex in single precision): a closed-form 3x3 solve per row and
    /// smoothing step, beside a row product of about 13 blocks. The setup still inverts the
    /// blocks in double for the Lanczos bound and the prolongator smoothing, then frees them.
    bool fine_inverses_on_the_fly = true;
    /// Split each aggregate into its sheets. On the fine level a sheet is a component of the
    /// aggregate's couplings whose 3x3 block is not rank-one (a contact or repulsion spring's
    /// k n n^T is, and so is a flat hinge's coupling of its two wing tips; membrane blocks are
    /// not); on a coarse level, two nodes are in one sheet when members of theirs were.
    /// Layers joined by normal springs slide over each other, so each needs its own in-plane
    /// translations and rotations, which the six rigid modes of an aggregate spanning the
    /// stack cannot give (bending the stack would shear it). Aggregation still follows the
    /// springs, so the per-layer pieces line up from layer to layer and the coarse space keeps
    /// the stack's common normal motion. Regular dropVertical at 40k: 69.5 -> 25.5 iterations
    /// at 2.2x SA's own memory; with aggregation_theta = 0.25, 78.5 -> 36.5 at 160k and
    /// 92.5 -> 54 at 361k, at 1.45x and 1.03x. Alone, irregular dropVertical, whose oblique
    /// springs bond the layers in shear, gets slower (30 -> 49.5 iterations at 361k)
    /// (bench/results/table-11-1/DV-regular-accordion.md, section 5); `split_bonded` keeps
    /// such aggregates whole. The `large` preset's.
    bool split_sheets = false;
    /// With `split_sheets`: aggregation's strength threshold is relative to each node's
    /// largest coupling within its sheet, not to its springs. On dropVertical the springs
    /// (dt^2 k against a vertex's mass) outweigh the membrane, so at aggregation_theta = 0.25
    /// the sheets' own couplings are weak, the aggregates follow the springs across the
    /// layers, and the split cuts them into small pieces with a heavy level 1.
    bool sheet_strength = false;
    /// With `split_sheets`: an aggregate whose springs between its sheets, summed as k n n^T,
    /// have a middle eigenvalue above this fraction of the largest stays whole, since oblique
    /// springs bond its layers in shear (0: split every aggregate).
    double split_bonded = 0;
    /// With `split_sheets`: an aggregate of at most this many nodes after the split (a piece
    /// the split cut off, or a small leftover) joins the larger neighbouring aggregate of its
    /// sheet it shares the most sheet couplings with (0: none). Each piece is a row of the
    /// coarse operator A_1, SA's largest array, with as many neighbours as a whole aggregate.
    /// On regular dropVertical at 160k (the `large` preset without it) 3 merges 3269 of
    /// 21265 fine aggregates: A_1 820k -> 562k blocks, SA+PPCG's memory 1.56x -> 1.39x
    /// Diag-PCG's, at 26.6 -> 27.1 iterations (bench/results/table-11-1/MERGE.md).
    int split_merge = 0;
    AggregateOrder aggregate_order = AggregateOrder::automatic;
    /// Correct the smoothed prolongator so that it maps the coarse near null space to the one
    /// smoothed with the whole A (`sa::preserve_modes`): the filter's lumping keeps the
    /// translations and loses the rotations, which carry a bending-dominated sheet's linear
    /// out-of-plane fields. P keeps its pattern (no memory), at one product of A with six
    /// vectors per prolongator step and a 6x6 solve per row in the setup.
    bool preserve_modes = false;
    /// The keys a scene gave beside the preset (set when read): under `auto` they hold at
    /// every size, as does any setting that differs from auto's.
    std::vector<std::string> given;

    /// Collects the keys a reader's object gives (see `given`).
    template <class R>
    struct GivenKeys {
      const R* reader;
      std::vector<std::string> keys;
      template <class T>
      void field(const char* key, T&, const FieldInfo&) { note(key); }
      template <class E, class Names>
      void choice(const char* key, E&, const Names&, const char*) { note(key); }
      void note(const char* key) {
        if (reader->has(key)) keys.emplace_back(key);
      }
    };
    /// The settings of a preset (`auto`: those below `large_from`).
    static Params of(SaPreset p);
    /// The settings the hierarchy uses for a fine level of `rows` nodes: under `auto` from
    /// `large_from` rows, `large`'s with the keys given and every setting that differs from
    /// auto's kept.
    Params resolved(int rows) const;

    template <class V>
    void visit(V& v) {
      v.choice("preset", preset, sa_preset_names,
               "named settings the others change: auto (the thesis' hierarchy, refreshed once per time step, below large_from vertices, large from there), thesis (rebuilt at every setup: Table 11.1), large (iterations bounded to 1M vertices and on stacked sheets)");
      if constexpr (requires { v.has("preset"); })
        if (v.has("preset")) {  // reading: the preset first, then the keys given beside it
          const SaPreset chosen = preset;
          *this = of(chosen);
        }
      visit_settings(v);
    }
    /// Every key but `preset`.
    template <class V>
    void visit_settings(V& v) {
      v.field("large_from", large_from, {Unit::none, Range::ge(1), "with preset auto: fine rows (vertices) from which the large settings apply"});
      v.field("theta", theta,
              {Unit::none, Range::open(0, 1), "strength threshold relative to the row's largest mu_ij; the prolongator is smoothed with the strong blocks"});
      v.field("aggregation_theta", aggregation_theta,
              {Unit::none, Range::closed_open(0, 1), "threshold of the couplings aggregation follows; 0: theta (the thesis)"});
      v.choice("strength", strength, soc_measure_names, "measure of the scaled block A_ii^-1/2 A_ij A_jj^-1/2");
      v.field("diagonal_dominance", diagonal_dominance,
              {Unit::none, Range::ge(0), "a node with sum_j mu_ij below this is special (relaxation only)"});
      v.field("coarse_size", coarse_size, {Unit::none, Range::ge(1), "stop coarsening at this many nodes or fewer"});
      v.field("max_levels", max_levels, {Unit::none, Range::closed(1, 30), "most levels of the hierarchy"});
      v.field("stall_ratio", stall_ratio, {Unit::none, Range::open_closed(0, 1), "stop when a level keeps more than this fraction of the nodes"});
      v.field("dense_limit", dense_limit, {Unit::none, Range::ge(1), "largest coarsest level (dofs) factorised densely; above, smoothing only"});
      v.field("qr_tolerance", qr_tolerance, {Unit::none, Range::open(0, 1), "relative drop tolerance of the local rank-revealing QR"});
      v.field("lanczos_steps", lanczos_steps, {Unit::none, Range::closed(1, 100), "generalised Lanczos steps for lambda_max(D^-1 A)"});
      v.choice("lambda_bound", lambda_bound, lambda_bound_names, "upper estimate of lambda_max(D^-1 A) from the Lanczos result");
      v.field("chebyshev_degree", chebyshev_degree, {Unit::none, Range::closed(1, 10), "degree of the Chebyshev smoother (pre and post)"});
      v.field("chebyshev_lower", chebyshev_lower, {Unit::none, Range::open(0, 1), "lower end of the damped interval, relative to lambda"});
      v.field("chebyshev_upper", chebyshev_upper, {Unit::none, Range::gt(0), "upper end of the damped interval, relative to lambda"});
      v.field("cycle_gamma", cycle_gamma,
              {Unit::none, Range::closed(1, 4), "coarse cycles per visit of the first cycle_gamma_levels coarse levels (1: V-cycle, 2: W there)"});
      v.field("cycle_gamma_levels", cycle_gamma_levels,
              {Unit::none, Range::closed(1, 30), "coarse levels, counted from level 1, that get cycle_gamma cycles"});
      v.field("prolongator_degree", prolongator_degree,
              {Unit::none, Range::closed(1, 3), "damped Jacobi steps of the prolongator smoother on the first prolongator_degree_levels levels"});
      v.field("prolongator_degree_levels", prolongator_degree_levels,
              {Unit::none, Range::closed(1, 30), "levels, from the fine one, whose prolongator gets prolongator_degree steps"});
      v.field("prolongator_truncation", prolongator_truncation,
              {Unit::none, Range::closed_open(0, 1), "drop the blocks of each prolongator row below this fraction of the row's largest (Frobenius norm); preserve_modes then repairs the rigid modes (0: keep all)"});
      v.choice("reuse", reuse, sa_reuse_names,
               "none: rebuild each setup; aggregates: keep the structure; frozen: keep everything; step: "
               "aggregates once per time step, the coarse levels kept between (the fine level reads the current matrix)");
      v.choice("prolongator_storage", prolongator_storage, value_storage_names,
               "storage of the prolongators' values: double or fixed16 (int16 with one scale per coarse dof); rounded before the Galerkin product, products in double");
      v.field("single_coarse_operators", single_coarse_operators,
              {Unit::none, Range::any(), "store the coarse operators in single precision (formed in double, rounded once; products in double)"});
      v.field("single_block_inverses", single_block_inverses,
              {Unit::none, Range::any(), "keep the smoother's block inverses in single precision after the setup (products in double)"});
      v.field("fine_inverses_on_the_fly", fine_inverses_on_the_fly,
              {Unit::none, Range::any(), "the fine level's smoother solves with A's diagonal blocks at each use instead of storing their inverses"});
      v.field("split_sheets", split_sheets,
              {Unit::none, Range::any(), "split each aggregate into its sheets: on the fine level the components of its couplings that are not rank-one (springs k n n^T are), on coarse levels those inherited"});
      v.field("sheet_strength", sheet_strength,
              {Unit::none, Range::any(), "with split_sheets: aggregation's strength threshold relative to each node's largest coupling within its sheet, not to its springs"});
      v.field("split_bonded", split_bonded,
              {Unit::none, Range::closed(0, 1), "with split_sheets: keep an aggregate whole when its springs between sheets, summed as k n n^T, have a middle eigenvalue above this fraction of the largest (0: split all)"});
      v.field("split_merge", split_merge,
              {Unit::none, Range::ge(0), "with split_sheets: an aggregate of at most this many nodes joins the neighbouring aggregate of its sheet it shares the most sheet couplings with (0: none)"});
      v.field("preserve_modes", preserve_modes,
              {Unit::none, Range::any(), "correct the smoothed prolongator, within its pattern, to map the coarse near null space to the fine one smoothed with the whole A (the filter loses the rotations)"});
      v.choice("aggregate_order", aggregate_order, aggregate_order_names,
               "numbering of the aggregates, the next level's row order: natural (by seed), rcm (reverse Cuthill-McKee, for locality of the coarse products) or auto (rcm where it halves the mean number distance of coupled aggregates)");
      if constexpr (requires { v.has("preset"); }) {  // reading: note the keys the object gave
        GivenKeys<V> g{&v, {}};
        Params probe;
        probe.visit_settings(g);
        given = std::move(g.keys);
      }
    }
  };
  static Checker validate(const Params& p);

  explicit SaAmg(const Params& prm);
  ~SaAmg();
  SaAmg(SaAmg&&) noexcept;
  SaAmg& operator=(SaAmg&&) noexcept;
  /// Forget every cached structure (the next `setup` rebuilds everything).
  Status analyze_pattern(const BlockCsr& A);
  /// A new time step begins: under reuse = step, the next setup refreshes the hierarchy.
  void begin_step() { step_begun_ = true; }
  /// Setups that built or refreshed the hierarchy (the others kept it) since construction.
  int refreshes() const { return refreshes_; }
  /// The last setup kept a hierarchy set up from another matrix (`frozen`, or `step` after
  /// the step's first setup): after a PCG breakdown, refreshing it is the remedy.
  bool kept() const { return kept_; }
  /// Build (or refresh, see `SaReuse`) the hierarchy from the prefiltered matrix A.
  /// ctx.positions is required (rotation modes); ctx.constraints, if given, filters K.
  /// Except under `frozen`, A must stay alive and unchanged while `apply` is used.
  Status setup(const BlockCsr& A, const SolveContext& ctx);
  /// The same for the prefiltered operator Ahat = S A S + Sigma (I - S) read from A through
  /// the per-vertex filters F (PPCG on the fly, no copy of Ahat): every block the setup and
  /// the fine-level smoother read is filtered as it is read, bitwise the block
  /// `prefilter_matrix` would store. Under `frozen` the private fine copy is prefiltered.
  Status setup(const BlockCsr& A, const SolveContext& ctx, const VertexFilterView& F);
  /// z = B r: one V(1,1) cycle from a zero guess.
  void apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) const;
  /// The same with `work` (resized to r's size) as the fine level's work vector: PCG lends
  /// its idle A p vector, so the hierarchy keeps no fine-size vector of its own. Without it
  /// the first `apply` allocates one.
  void apply(const Eigen::VectorXd& r, Eigen::VectorXd& z, Eigen::VectorXd& work) const;
  PreconditionerInfo info() const;
  const SaStats& stats() const { return stats_; }
  /// After a PCG breakdown r^T B r <= 0: the Lanczos estimate of lambda_max(D_l^-1 A_l) fell
  /// below the true value on some level (a few stiff, localised modes, e.g. barrier pairs),
  /// so the Chebyshev polynomial goes negative there and the cycle is indefinite. Raises each
  /// level's lambda until the interval's top chebyshev_upper * lambda reaches the guaranteed
  /// bound ||D_l^-1 A_l||_inf >= lambda_max (Gershgorin on D^-1 A), which makes every smoother,
  /// and so the cycle, SPD again (methods/multigrid §5.2, Appendix A). Returns whether any level changed; the next setup estimates afresh.
  bool widen_smoothers();
  /// Levels widened by `widen_smoothers` since construction.
  int widened_levels() const { return widened_; }

  // Inspection (tests and benchmarks).
  int levels() const;
  /// A_l as a dense matrix (small problems only).
  Eigen::MatrixXd level_matrix(int l) const;
  /// P_l (l < levels() - 1) as a dense matrix.
  Eigen::MatrixXd prolongator(int l) const;
  /// One Chebyshev sweep of level l: x <- x + p-smoothing of A_l x = f.
  void smooth(int l, const Eigen::VectorXd& f, Eigen::VectorXd& x) const;

 private:
  struct Impl;  // the levels (linear/sa_internal.hpp)
  Params prm_;
  Params active_;  // prm_ resolved for the last setup's size (`Params::resolved`)
  SaStats stats_;
  int widened_ = 0;
  bool step_begun_ = true;  // reuse = step: no setup since the last begin_step
  bool kept_ = false;       // the last setup kept the hierarchy (see kept())
  int refreshes_ = 0;
  std::unique_ptr<Impl> impl_;
};

static_assert(Preconditioner<SaAmg>);

}  // namespace weft::linear
