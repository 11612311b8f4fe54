// pipeline/distributed.h without MPI: one process.

#include <cstdlib>
#include <string>

#include "chronomap/core/error.h"
#include "chronomap/pipeline/distributed.h"

namespace chronomap {

bool mpiBuilt() { return false; }

Ranks::Ranks() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE"}) {
    const char* value = std::getenv(name);
    if (value && std::atoi(value) > 1) {
      throw UsageError("this chronomap was built without MPI (CMake CHRONOMAP_MPI): run it without mpirun, or with "
                       "-np 1");
    }
  }
}

Ranks::~Ranks() = default;

std::optional<BuildResult> buildOnRanks(const BuildSettings& settings, const Ranks&) { return build(settings); }

}  // namespace chronomap
