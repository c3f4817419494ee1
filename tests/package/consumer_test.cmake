# PackageConsumer: installs the build tree into a fresh prefix, configures and builds
# examples/consumer against it with find_package(Streetlight), and runs the consumer. Then, from
# a working directory without models/, the installed tools and (with -DPYTHON) the installed
# Python module must find the released weights the install put under the prefix, not the source
# tree's.
# Arguments: -DBUILD_DIR= -DSOURCE_DIR= -DWORK_DIR= [-DLAUNCHER=ccache] [-DPYTHON=python3 -DPYTHON_DIR=lib/...]
foreach(_v BUILD_DIR SOURCE_DIR WORK_DIR)
  if(NOT ${_v})
    message(FATAL_ERROR "consumer_test.cmake needs -D${_v}=...")
  endif()
endforeach()
file(REMOVE_RECURSE "${WORK_DIR}")
file(MAKE_DIRECTORY "${WORK_DIR}")
set(_prefix "${WORK_DIR}/prefix")
function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE _rc OUTPUT_VARIABLE _out ERROR_VARIABLE _err
                  WORKING_DIRECTORY "${WORK_DIR}")
  if(NOT _rc EQUAL 0)
    message(FATAL_ERROR "failed (${_rc}): ${ARGN}\n${_out}\n${_err}")
  endif()
  set(LAST_OUTPUT "${_out}" PARENT_SCOPE)
endfunction()
run(${CMAKE_COMMAND} --install "${BUILD_DIR}" --prefix "${_prefix}")
if(NOT EXISTS "${_prefix}/lib/cmake/Streetlight/StreetlightConfig.cmake")
  message(FATAL_ERROR "no StreetlightConfig.cmake under ${_prefix}")
endif()
set(_launcher "")
if(LAUNCHER)
  set(_launcher "-DCMAKE_CXX_COMPILER_LAUNCHER=${LAUNCHER}")
endif()
run(${CMAKE_COMMAND} -S "${SOURCE_DIR}/examples/consumer" -B "${WORK_DIR}/build" "-DCMAKE_PREFIX_PATH=${_prefix}"
    -DCMAKE_BUILD_TYPE=Release ${_launcher})
run(${CMAKE_COMMAND} --build "${WORK_DIR}/build")
run("${WORK_DIR}/build/streetlight_consumer")
message(STATUS "${LAST_OUTPUT}")
if(NOT LAST_OUTPUT MATCHES "gradcheck ok")
  message(FATAL_ERROR "unexpected consumer output: ${LAST_OUTPUT}")
endif()

# The installed tools and module, run from WORK_DIR (no models/ there), find the installed weights.
file(REAL_PATH "${_prefix}" _real_prefix)
set(_models "${_real_prefix}/share/streetlight/models")
foreach(_f streetlight.safetensors sun_glare.safetensors README.md)
  if(NOT EXISTS "${_models}/${_f}")
    message(FATAL_ERROR "the install lacks ${_models}/${_f}")
  endif()
endforeach()
set(_clean_env ${CMAKE_COMMAND} -E env --unset=STREETLIGHT_MODEL --unset=STREETLIGHT_SUN_GLARE)
run(${_clean_env} "${_prefix}/bin/streetlight-insert" --version)
if(NOT LAST_OUTPUT MATCHES "released model: ${_models}/streetlight.safetensors\n"
   OR NOT LAST_OUTPUT MATCHES "sun-glare detector: ${_models}/sun_glare.safetensors\n")
  message(FATAL_ERROR "the installed streetlight-insert does not name the installed weights:\n${LAST_OUTPUT}")
endif()
if(PYTHON)
  run(${_clean_env} "PYTHONPATH=${_prefix}/${PYTHON_DIR}" "${PYTHON}" -c
      "import streetlight\nprint(streetlight.__file__)\nprint(streetlight.Estimator().checkpoint)")
  if(NOT LAST_OUTPUT MATCHES "^${_real_prefix}/${PYTHON_DIR}/streetlight[^\n]*\n${_models}/streetlight.safetensors\n")
    message(FATAL_ERROR "the installed module is not the one imported, or does not load the installed weights:\n${LAST_OUTPUT}")
  endif()
endif()
file(REMOVE_RECURSE "${WORK_DIR}")
