# The training-records store (ROS-free, Qt-free), its command-line tool and its tests. Included from
# src/eyesi_gui/CMakeLists.txt after find_package(SQLite3 OpenSSL nlohmann_json).

file(GLOB EYESI_RECORDS_SOURCES CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/src/core/records/*.cpp)
add_library(eyesi_records STATIC ${EYESI_RECORDS_SOURCES})
# PIC: the console's nodelet/shared objects link this static library.
set_target_properties(eyesi_records PROPERTIES POSITION_INDEPENDENT_CODE ON)
target_include_directories(eyesi_records PUBLIC ${CMAKE_CURRENT_SOURCE_DIR}/include)
# The result JSON is read by the simulator's one reader (vrm_sim/result/session_result.h).
# The records server's client (issue 41): libpq from Debian's libpq-dev.
find_package(PkgConfig REQUIRED)
pkg_check_modules(LIBPQ REQUIRED IMPORTED_TARGET libpq)
target_link_libraries(eyesi_records PUBLIC vrm_session_result SQLite::SQLite3 OpenSSL::Crypto PkgConfig::LIBPQ)
target_link_libraries(eyesi_records PRIVATE nlohmann_json::nlohmann_json)
target_compile_options(eyesi_records PRIVATE -Wall -Wextra)

# Its command line: vrm_sim's vrm_cli (boost::program_options).
find_package(Boost REQUIRED COMPONENTS program_options)
add_executable(records tools/records.cpp)
target_link_libraries(records eyesi_records vrm_cli)
install(TARGETS records RUNTIME DESTINATION ${CATKIN_PACKAGE_BIN_DESTINATION})

# The trajectories of a session bag for the records (issue 41): the one ROS part, reading the bag with rosbag.
find_package(rosbag REQUIRED)
add_executable(session_trajectory tools/session_trajectory.cpp)
target_include_directories(session_trajectory PRIVATE ${rosbag_INCLUDE_DIRS})
target_link_libraries(session_trajectory eyesi_records vrm_cli ${rosbag_LIBRARIES} ${catkin_LIBRARIES})
add_dependencies(session_trajectory vrm_msgs_generate_messages_cpp)
install(TARGETS session_trajectory RUNTIME DESTINATION ${CATKIN_PACKAGE_BIN_DESTINATION})
install(TARGETS eyesi_records ARCHIVE DESTINATION ${CATKIN_PACKAGE_LIB_DESTINATION})

# The records benchmark (issue 41): SQLite vs a throw-away PostgreSQL cluster; `./scripts/bench.sh records`.
add_executable(bench_records bench/bench_records.cpp)
target_link_libraries(bench_records eyesi_records vrm_cli nlohmann_json::nlohmann_json)
target_compile_definitions(bench_records PRIVATE EYESI_GUI_SOURCE_DIR="${CMAKE_CURRENT_SOURCE_DIR}")
set_target_properties(bench_records PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CATKIN_DEVEL_PREFIX}/lib/${PROJECT_NAME})

if(CATKIN_ENABLE_TESTING)
  catkin_add_gtest(test_records test/test_records.cpp)
  if(TARGET test_records)
    target_link_libraries(test_records eyesi_records nlohmann_json::nlohmann_json gtest_main)
    # The simulator's reference results (real scenario_manager output) and the tool, run as a subprocess.
    target_compile_definitions(test_records PRIVATE EYESI_TEST_BAGS="${CMAKE_CURRENT_SOURCE_DIR}/../vrm_sim/test/bags"
                                                    EYESI_RECORDS_TOOL="$<TARGET_FILE:records>")
    # records_export.py and centre_sync.py (scripts/test.sh) run session_trajectory too.
    add_dependencies(test_records records session_trajectory)
  endif()
endif()
