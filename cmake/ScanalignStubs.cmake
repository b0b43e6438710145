# Type stubs (.pyi) of the compiled module, generated after each build of _core with
# pybind11-stubgen from the docstrings and signatures written once in the C++ bindings, and
# installed beside the module so editors and mypy see every class. The module is imported
# from a staging folder holding only the package's __init__.py (it imports nothing eagerly).
# Skipped with a message when pybind11-stubgen is not installed in the build's Python.
execute_process(COMMAND ${Python_EXECUTABLE} -c "import pybind11_stubgen"
                RESULT_VARIABLE _scanalign_no_stubgen OUTPUT_QUIET ERROR_QUIET)
if(_scanalign_no_stubgen)
  message(STATUS "scanalign: pybind11-stubgen not found, no type stubs for _core (pip install pybind11-stubgen)")
  return()
endif()
set(_stage ${CMAKE_BINARY_DIR}/stubgen)
add_custom_command(TARGET _core POST_BUILD
  COMMAND ${CMAKE_COMMAND} -E make_directory ${_stage}/scanalign
  COMMAND ${CMAKE_COMMAND} -E copy ${PROJECT_SOURCE_DIR}/python/scanalign/__init__.py ${_stage}/scanalign/__init__.py
  COMMAND ${CMAKE_COMMAND} -E copy $<TARGET_FILE:_core> ${_stage}/scanalign/
  COMMAND ${CMAKE_COMMAND} -E rm -rf ${_stage}/out
  COMMAND ${CMAKE_COMMAND} -E env PYTHONPATH=${_stage}
          ${Python_EXECUTABLE} -m pybind11_stubgen scanalign._core -o ${_stage}/out --exit-code
  COMMENT "Type stubs for scanalign._core (pybind11-stubgen)"
  VERBATIM)
install(DIRECTORY ${_stage}/out/scanalign/_core DESTINATION scanalign COMPONENT python)
