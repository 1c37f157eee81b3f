# soil_add_fmu(ID SOURCES ... DESCRIPTION_SOURCES ... [LIBS ...] [DEFINITIONS ...])
# builds the FMI 2.0 co-simulation FMU ${CMAKE_BINARY_DIR}/fmu/ID.fmu (docs/fmi.md):
#   * binaries/linux64/ID.so: the fmi2 functions (fmu_export/common) and SOURCES; only the
#     fmi2* functions are exported (C linkage, default visibility; a version script hides
#     the rest, including everything of the static libraries linked in);
#   * modelDescription.xml: written by ID_describe (DESCRIPTION_SOURCES + the XML writer) from
#     the same variable table the .so checks its calls against;
#   * zipped with cmake -E tar --format=zip. Target: ID_fmu (built by default).
set(FMU_COMMON_DIR ${PROJECT_SOURCE_DIR}/fmu_export/common)

function(soil_add_fmu id)
  cmake_parse_arguments(F "" "" "SOURCES;DESCRIPTION_SOURCES;LIBS;DEFINITIONS" ${ARGN})
  set(stage ${CMAKE_BINARY_DIR}/fmu/${id})
  add_library(${id} SHARED ${FMU_COMMON_DIR}/fmi2_functions.cpp ${FMU_COMMON_DIR}/slave.cpp
              ${FMU_COMMON_DIR}/description.cpp ${F_SOURCES} ${F_DESCRIPTION_SOURCES})
  set_target_properties(${id} PROPERTIES PREFIX "" OUTPUT_NAME ${id}
    LIBRARY_OUTPUT_DIRECTORY ${stage}/binaries/linux64
    CXX_VISIBILITY_PRESET hidden VISIBILITY_INLINES_HIDDEN ON)
  target_include_directories(${id} PRIVATE ${FMU_COMMON_DIR} ${PROJECT_SOURCE_DIR}/mbs_adapters/fmu/include)
  target_compile_definitions(${id} PRIVATE ${F_DEFINITIONS})
  target_link_libraries(${id} PRIVATE ${F_LIBS})
  target_link_options(${id} PRIVATE -Wl,--version-script=${FMU_COMMON_DIR}/fmi2.map -Wl,--no-undefined
    -Wl,--exclude-libs,ALL)
  set_property(TARGET ${id} APPEND PROPERTY LINK_DEPENDS ${FMU_COMMON_DIR}/fmi2.map)
  soil_warnings(${id})

  add_executable(${id}_describe ${FMU_COMMON_DIR}/describe_main.cpp ${FMU_COMMON_DIR}/description.cpp
                 ${F_DESCRIPTION_SOURCES})
  set_target_properties(${id}_describe PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/fmu/tools)
  target_include_directories(${id}_describe PRIVATE ${FMU_COMMON_DIR} ${PROJECT_SOURCE_DIR}/mbs_adapters/fmu/include)
  target_compile_definitions(${id}_describe PRIVATE ${F_DEFINITIONS})
  target_link_libraries(${id}_describe PRIVATE ${F_LIBS})
  soil_warnings(${id}_describe)

  set(fmu ${CMAKE_BINARY_DIR}/fmu/${id}.fmu)
  add_custom_command(OUTPUT ${fmu}
    COMMAND $<TARGET_FILE:${id}_describe> ${stage}/modelDescription.xml
    COMMAND ${CMAKE_COMMAND} -E rm -f ${fmu}
    COMMAND ${CMAKE_COMMAND} -E chdir ${stage} ${CMAKE_COMMAND} -E tar cf ${fmu} --format=zip
            modelDescription.xml binaries/linux64/${id}.so
    DEPENDS ${id} ${id}_describe
    COMMENT "Packing FMU ${id}.fmu")
  add_custom_target(${id}_fmu ALL DEPENDS ${fmu})
endfunction()
