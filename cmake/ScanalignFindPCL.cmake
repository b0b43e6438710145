# Finds PCL 1.13 the way Debian ships it.
#
# Debian's PCLConfig.cmake loads VTK, whose exported targets reference MPI::MPI_C even
# when MPI is not installed. Defining an empty imported target first lets the
# configuration succeed without pulling in MPI (scanalign never uses it).
if(NOT TARGET MPI::MPI_C)
  add_library(MPI::MPI_C INTERFACE IMPORTED)
endif()
find_package(PCL 1.10 REQUIRED COMPONENTS common kdtree search features filters registration)
