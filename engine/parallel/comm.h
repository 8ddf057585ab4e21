#pragma once
/// \file The thin MPI layer: the process's ranks, reductions and the byte exchanges the
/// domain decomposition needs. The only header besides domain.h that knows MPI exists; without
/// MPI_Init (tests, a plain `mpm run`) every call is the one-rank identity.

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace mpm::parallel {

/// MPI for the life of the program: MPI_Init on construction when started by a launcher
/// (mpirun or srun set OMPI_COMM_WORLD_SIZE, PMI_SIZE or PMIX_RANK), MPI_Finalize on
/// destruction. Only the command line (engine/cli/cli.cpp) creates one.
class Session {
 public:
  /// Initialises MPI (no threads call MPI: MPI_THREAD_FUNNELED).
  Session(int& argc, char**& argv);
  /// Finalises MPI if this object initialised it.
  ~Session();
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;

 private:
  bool owns_ = false;
};

/// This process's rank, 0 without MPI.
int rank();
/// Number of ranks, 1 without MPI.
int ranks();
/// Ends every rank at once (MPI_Abort) with `code`: for a failure only one rank saw.
[[noreturn]] void abort_all(int code);

/// Communication counters of this rank.
struct CommStats {
  double seconds = 0;          ///< Wall time inside MPI calls, s.
  std::uint64_t bytes = 0;     ///< Bytes this rank sent.
  std::uint64_t messages = 0;  ///< Point-to-point messages (and collectives) this rank started.
};
/// The counters of this rank so far.
CommStats& comm_stats();

/// Smallest value over all ranks.
double min_all(double x);
/// Largest value over all ranks.
double max_all(double x);
/// Sum over all ranks (rank order is fixed by MPI_Reduce's tree: the same every run).
double sum_all(double x);
/// Sum over all ranks.
std::uint64_t sum_all(std::uint64_t x);
/// Element-wise sum over all ranks (every rank passes the same size), on every rank.
std::vector<std::uint64_t> sum_all(std::vector<std::uint64_t> x);
/// True if `x` is true on any rank.
bool any_all(bool x);
/// Rank 0's value of `x` on every rank.
void broadcast(std::string& x);
/// Rank 0's values on every rank (`x` is resized).
void broadcast(std::vector<int>& x);
/// Rank 0's value on every rank.
void broadcast(int& x);
/// `local` of the lowest rank where it is not empty, on every rank ("" if empty on all): the
/// cause of a failure only some ranks saw.
std::string first_nonempty(const std::string& local);
/// Every rank's value, in rank order, on every rank.
std::vector<double> all_gather(double x);
/// Every rank's `x` (the same size on every rank), concatenated in rank order, on every rank.
std::vector<double> all_gather(const std::vector<double>& x);
/// Sum over all ranks added in rank order (0, 1, ...) on every rank: the same bits every run
/// for the same partial values, whatever MPI's reduction tree.
double sum_in_rank_order(double x);
/// Every rank's value, in rank order, on every rank.
std::vector<std::uint64_t> all_gather(std::uint64_t x);

/// Sends `send` to rank `to` and receives from rank `from` (either may be -1: none); returns
/// what was received (sizes are exchanged first).
std::vector<char> send_receive(const std::vector<char>& send, int to, int from);
/// Sends buffer r of `send` to rank r and returns what each rank sent here, in rank order.
std::vector<std::vector<char>> all_to_all(const std::vector<std::vector<char>>& send);

/// Test-only failure hook: true if the environment sets MPM_TEST_FAIL_RANK (the rank) and
/// MPM_TEST_FAIL_SUBSTEP (the substep count at which it fails); the run then gets a
/// `test_failure` stage (engine/step/simulation.cpp). Never set by a scene.
bool test_failure_requested();
/// The test_failure stage: throws std::runtime_error on the requested rank at the requested
/// substep (counted from 1, as in report.yaml), so tests can check that one rank's failure
/// stops every rank cleanly.
void test_failure_point(std::size_t substeps);

}  // namespace mpm::parallel
