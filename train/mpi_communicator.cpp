// MPI communicator. See mpi_communicator.h.
#include "train/mpi_communicator.h"

#include <algorithm>
#include <climits>
#include <cstdlib>

#include "util/error.h"

#ifdef STREETLIGHT_WITH_MPI
#include <mpi.h>
#endif

namespace sl::train {

namespace {

bool launched_by_mpi() {
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"})
    if (std::getenv(v)) return true;
  return false;
}

}  // namespace

#ifdef STREETLIGHT_WITH_MPI

namespace {

class MpiCommunicator : public Communicator {
 public:
  MpiCommunicator() {
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
  }
  ~MpiCommunicator() override {
    int finalised = 0;
    MPI_Finalized(&finalised);
    if (!finalised) MPI_Finalize();
  }
  int rank() const override { return rank_; }
  int size() const override { return size_; }
  std::string backend() const override { return "mpi"; }
  void allreduce_sum(float* data, int64_t count) override { chunked(data, count, MPI_FLOAT, MPI_SUM); }
  void allreduce_sum(double* data, int64_t count) override { chunked(data, count, MPI_DOUBLE, MPI_SUM); }
  void allreduce_max(double* data, int64_t count) override { chunked(data, count, MPI_DOUBLE, MPI_MAX); }
  void broadcast(float* data, int64_t count, int root) override {
    for (int64_t at = 0; at < count; at += INT_MAX)
      MPI_Bcast(data + at, static_cast<int>(std::min<int64_t>(count - at, INT_MAX)), MPI_FLOAT, root, MPI_COMM_WORLD);
  }
  void barrier() override { MPI_Barrier(MPI_COMM_WORLD); }
  [[noreturn]] void abort(int code) override {
    MPI_Abort(MPI_COMM_WORLD, code);
    std::_Exit(code);  // MPI_Abort does not return; this only satisfies [[noreturn]]
  }

 private:
  template <class T>
  void chunked(T* data, int64_t count, MPI_Datatype type, MPI_Op op) {
    for (int64_t at = 0; at < count; at += INT_MAX)
      MPI_Allreduce(MPI_IN_PLACE, data + at, static_cast<int>(std::min<int64_t>(count - at, INT_MAX)), type, op,
                    MPI_COMM_WORLD);
  }
  int rank_ = 0, size_ = 1;
};

}  // namespace

bool mpi_built() { return true; }

std::shared_ptr<Communicator> mpi_communicator_if_launched(int* argc, char*** argv) {
  if (!launched_by_mpi()) return nullptr;
  int initialised = 0;
  MPI_Initialized(&initialised);
  if (!initialised) {
    int provided = 0;
    MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided);
  }
  return std::make_shared<MpiCommunicator>();
}

#else

bool mpi_built() { return false; }

std::shared_ptr<Communicator> mpi_communicator_if_launched(int*, char***) {
  // Several copies of a build without MPI would each train alone and overwrite one output.
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE"}) {
    const char* n = std::getenv(v);
    SL_CHECK(!launched_by_mpi() || !n || std::atoi(n) <= 1, "started by an MPI launcher with ", v, "=", n,
             ", but this build has no MPI: install libopenmpi-dev (scripts/install_deps.sh --mpi) and rebuild");
  }
  return nullptr;
}

#endif

}  // namespace sl::train
