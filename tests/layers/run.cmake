# ctest driver for the layer check: the real tree passes, and a copy of one real file moved
# into a lower layer (an upward include) fails it.
#   cmake -DSOURCE_DIR=<repo> -DRULES=... -DWORK_DIR=<scratch> -P run.cmake
execute_process(COMMAND ${CMAKE_COMMAND} -DSOURCE_DIR=${SOURCE_DIR} "-DRULES=${RULES}"
                        -P ${SOURCE_DIR}/cmake/check_layers.cmake
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "the source tree breaks its layers:\n${out}${err}")
endif()
# A scratch tree: rover (below estimators) gets a header that includes the EKF.
file(REMOVE_RECURSE ${WORK_DIR})
file(MAKE_DIRECTORY ${WORK_DIR}/include/traverse/rover ${WORK_DIR}/include/traverse/estimators)
file(WRITE ${WORK_DIR}/include/traverse/estimators/ekf.h "#pragma once\n")
file(WRITE ${WORK_DIR}/include/traverse/rover/upward.h
     "#pragma once\n#include \"traverse/core/types.h\"\n#include \"traverse/estimators/ekf.h\"\n")
execute_process(COMMAND ${CMAKE_COMMAND} -DSOURCE_DIR=${WORK_DIR} "-DRULES=${RULES}"
                        -P ${SOURCE_DIR}/cmake/check_layers.cmake
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(rc EQUAL 0)
  message(FATAL_ERROR "an upward include (rover -> estimators) passed the layer check")
endif()
if(NOT err MATCHES "include/traverse/rover/upward.h: layer 'rover' includes 'estimators'")
  message(FATAL_ERROR "the layer check failed without naming the file and layers:\n${err}")
endif()
message(STATUS "layer check: source tree clean; upward include rejected")
