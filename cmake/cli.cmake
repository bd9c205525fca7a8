# The tools' command line: the flag library gmm_mcl_cli (src/cli, include/gmm_mcl/cli; the
# filter's flags from the parameter table) and gmm_mcl_add_tool(), which every offline tool uses.
if(Boost_PROGRAM_OPTIONS_FOUND)
  add_library(gmm_mcl_cli STATIC src/cli/command_line.cpp)
  target_link_libraries(gmm_mcl_cli PUBLIC gmm_mcl_core Boost::program_options)
else()
  # Building a tool then stops here with the reason instead of a linker error.
  add_custom_target(gmm_mcl_cli_missing
    COMMAND ${CMAKE_COMMAND} -E echo "gmm_mcl: the tools need boost program_options, not found:"
            "install libboost-program-options-dev, or set GMM_MCL_BOOST_DIR to a copy made by"
            "scripts/gpu_deps.sh"
    COMMAND ${CMAKE_COMMAND} -E false
    VERBATIM)
endif()
# gmm_mcl_add_tool(TARGET SOURCE... [OUTPUT_NAME NAME] LIBS LIB...): an offline tool on the
# flag library (the program is NAME where the target's name is taken by a library).
function(gmm_mcl_add_tool target)
  cmake_parse_arguments(T "" "OUTPUT_NAME" "LIBS" ${ARGN})
  add_executable(${target} ${T_UNPARSED_ARGUMENTS})
  if(TARGET gmm_mcl_cli)
    target_link_libraries(${target} PRIVATE ${T_LIBS} gmm_mcl_cli)
  else()
    target_link_libraries(${target} PRIVATE ${T_LIBS})
    add_dependencies(${target} gmm_mcl_cli_missing)
  endif()
  if(T_OUTPUT_NAME)
    set_target_properties(${target} PROPERTIES OUTPUT_NAME ${T_OUTPUT_NAME})
  endif()
endfunction()
