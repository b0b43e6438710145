# Finds PCL 1.13 the way Debian ships it: required when SCANALIGN_PCL_REQUIRED is true (the
# default, and SCANALIGN_WITH_PCL=ON), quietly otherwise (AUTO; PCL_FOUND tells).
#
# Debian's PCLConfig.cmake loads VTK, whose exported targets reference MPI::MPI_C even
# when MPI is not installed. Defining an empty imported target first lets the
# configuration succeed without pulling in MPI (scanalign never uses it).
if(NOT TARGET MPI::MPI_C)
  add_library(MPI::MPI_C INTERFACE IMPORTED)
endif()
if(NOT DEFINED SCANALIGN_PCL_REQUIRED OR SCANALIGN_PCL_REQUIRED)
  find_package(PCL 1.10 REQUIRED COMPONENTS common kdtree search features filters registration)
else()
  find_package(PCL 1.10 QUIET COMPONENTS common kdtree search features filters registration)
endif()
