// The MPI implementation of train/distributed.h's Communicator (Open MPI or any MPI-3 library),
// compiled only when CMake found MPI (STREETLIGHT_WITH_MPI); docs/DISTRIBUTED.md.
//
// Contract:
// - mpi_communicator_if_launched() initialises MPI (MPI_THREAD_FUNNELED: only the thread that
//   calls it makes MPI calls; OpenMP threads and the batch prefetch thread never do) and returns
//   a communicator over MPI_COMM_WORLD when this process was started by an MPI launcher
//   (mpirun / mpiexec set OMPI_COMM_WORLD_SIZE, PMI_SIZE or PMIX_RANK). Otherwise, or in a
//   build without MPI, it returns nullptr and MPI is never initialised, so a plain run needs no
//   MPI runtime at all. MPI is finalised when the communicator is destroyed. A build without
//   MPI started by a launcher with more than one process throws sl::Error saying so.
// - Errors of MPI calls are fatal (MPI's default handler): a rank that dies makes the launcher
//   stop the job; abort() calls MPI_Abort on MPI_COMM_WORLD.
#pragma once
#include <memory>

#include "train/distributed.h"

namespace sl::train {

bool mpi_built();
std::shared_ptr<Communicator> mpi_communicator_if_launched(int* argc, char*** argv);

}  // namespace sl::train
