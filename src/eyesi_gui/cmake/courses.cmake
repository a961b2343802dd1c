# Courses with pass marks (issue 35). Included at the end of src/eyesi_gui/CMakeLists.txt, after records.cmake
# (eyesi_records, whose source glob holds src/core/records/course.cpp) and the console (eyesi_console, when Qt5 was
# found).

# The course file goes through the project's one strict YAML reader.
target_link_libraries(eyesi_records PUBLIC vrm_yaml)
install(DIRECTORY config/courses DESTINATION ${CATKIN_PACKAGE_SHARE_DESTINATION}/config)

if(TARGET eyesi_console)
  target_sources(eyesi_console PRIVATE src/console/course_panel.h src/console/course_panel.cpp)
endif()

if(CATKIN_ENABLE_TESTING)
  # The reader and the progress; the shipped course checked against the shipped scenes through vrm_sim's scene loader.
  catkin_add_gtest(test_course test/test_course.cpp)
  if(TARGET test_course)
    target_link_libraries(test_course eyesi_records vrm_scene gtest_main)
    target_compile_definitions(test_course PRIVATE EYESI_COURSES_DIR="${CMAKE_CURRENT_SOURCE_DIR}/config/courses"
                                                   VRM_SIM_DIR="${CMAKE_CURRENT_SOURCE_DIR}/../vrm_sim")
  endif()
  if(TARGET eyesi_console)
    # The console's course widgets, offscreen with a fake simulator link (like test_console_widgets).
    catkin_add_gtest(test_console_course test/test_console_course.cpp)
    if(TARGET test_console_course)
      target_link_libraries(test_console_course eyesi_console Qt5::Test gtest)
      target_compile_definitions(test_console_course PRIVATE EYESI_COURSES_DIR="${CMAKE_CURRENT_SOURCE_DIR}/config/courses")
    endif()
  endif()
endif()

# The validity benchmark (issue 35): seeded expert, intermediate and novice cohorts carry out the course's steps
# through the simulation core; `./scripts/bench.sh validity` finds it in devel/lib like every bench_*. A smoke test
# (test_validity_bench) runs its --quick form.
add_executable(bench_validity bench/bench_validity.cpp ${CMAKE_CURRENT_SOURCE_DIR}/../vrm_sim/test/support/source_package.cpp)
target_link_libraries(bench_validity eyesi_records vrm_world vrm_cli nlohmann_json::nlohmann_json)
target_compile_definitions(bench_validity PRIVATE EYESI_GUI_SOURCE_DIR="${CMAKE_CURRENT_SOURCE_DIR}"
                                                  VRM_SIM_PACKAGE_DIR="${CMAKE_CURRENT_SOURCE_DIR}/../vrm_sim")
set_target_properties(bench_validity PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CATKIN_DEVEL_PREFIX}/lib/${PROJECT_NAME})
if(CATKIN_ENABLE_TESTING)
  catkin_add_gtest(test_validity_bench test/test_validity_bench.cpp)
  if(TARGET test_validity_bench)
    add_dependencies(test_validity_bench bench_validity)
    target_link_libraries(test_validity_bench nlohmann_json::nlohmann_json gtest_main)
    target_include_directories(test_validity_bench PRIVATE ${vrm_scene_SOURCE_DIR}/test/support)  # run_process.h
    target_compile_definitions(test_validity_bench PRIVATE BENCH_VALIDITY="$<TARGET_FILE:bench_validity>")
  endif()
endif()
