# Every dependency becomes an imported target. A missing one stops configure with a
# single line naming the Debian package that provides it (tools/setup.sh installs all).
include(FindPkgConfig)

function(softcontact_missing what package)
  message(FATAL_ERROR "softcontact: ${what} not found: install the Debian package '${package}' "
                      "(or run 'bash tools/setup.sh', which installs every dependency)")
endfunction()

find_package(PkgConfig QUIET)
if(NOT PKG_CONFIG_FOUND)
  softcontact_missing("pkg-config" "pkg-config")
endif()

find_package(MPI QUIET COMPONENTS C CXX)
if(NOT MPI_FOUND)
  softcontact_missing("MPI (Open MPI)" "libopenmpi-dev")
endif()
find_program(SOFTCONTACT_MPIEXEC NAMES mpiexec mpirun)
if(NOT SOFTCONTACT_MPIEXEC)
  softcontact_missing("mpiexec" "openmpi-bin")
endif()

find_package(OpenMP QUIET COMPONENTS CXX)
if(NOT OpenMP_CXX_FOUND)
  softcontact_missing("OpenMP" "libgomp1 (comes with g++)")
endif()

pkg_check_modules(PETSC QUIET IMPORTED_TARGET petsc)
if(NOT PETSC_FOUND)
  softcontact_missing("PETSc" "petsc-dev")
endif()

pkg_check_modules(HDF5 QUIET IMPORTED_TARGET hdf5-openmpi)
if(NOT HDF5_FOUND)
  softcontact_missing("parallel HDF5" "libhdf5-openmpi-dev")
endif()

pkg_check_modules(YAMLCPP QUIET IMPORTED_TARGET yaml-cpp)
if(NOT YAMLCPP_FOUND)
  softcontact_missing("yaml-cpp" "libyaml-cpp-dev")
endif()

find_package(Eigen3 3.3 QUIET NO_MODULE)
if(NOT TARGET Eigen3::Eigen)
  softcontact_missing("Eigen" "libeigen3-dev")
endif()

find_path(METIS_INCLUDE_DIR metis.h)
find_library(METIS_LIBRARY metis)
if(NOT METIS_INCLUDE_DIR OR NOT METIS_LIBRARY)
  softcontact_missing("METIS" "libmetis-dev")
endif()
add_library(METIS::METIS UNKNOWN IMPORTED)
set_target_properties(METIS::METIS PROPERTIES IMPORTED_LOCATION "${METIS_LIBRARY}"
                      INTERFACE_INCLUDE_DIRECTORIES "${METIS_INCLUDE_DIR}")

if(SOFTCONTACT_WITH_TESTS)
  find_package(GTest QUIET)
  if(NOT GTest_FOUND)
    softcontact_missing("GoogleTest" "libgtest-dev")
  endif()
endif()
if(SOFTCONTACT_WITH_BENCHMARKS)
  find_package(benchmark QUIET)
  if(NOT benchmark_FOUND)
    softcontact_missing("Google Benchmark" "libbenchmark-dev")
  endif()
endif()
