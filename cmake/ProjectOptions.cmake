# One place for warnings and sanitizers. Applied to the project's own targets only.
add_library(lidartag_warnings INTERFACE)
target_compile_options(lidartag_warnings INTERFACE
  -Wall -Wextra -Wpedantic -Wconversion -Wsign-conversion -Wshadow -Wnon-virtual-dtor
  -Wold-style-cast -Wcast-align -Woverloaded-virtual -Wnull-dereference)
if(CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
  # `&` on bools is deliberate where a loop must stay branch-free to vectorise (edge_features.cpp);
  # GCC has no such warning, so both compilers accept the same code.
  target_compile_options(lidartag_warnings INTERFACE -Wno-bitwise-instead-of-logical)
endif()
# Warnings are errors where developers build (scripts/run-tests.sh turns LIDARTAG_WERROR on for
# its RelWithDebInfo and Release builds), never by default: a user's or packager's build of any
# build type must not break on a new compiler's warning or a false positive (GCC 12's -Wrestrict
# at -O3, bug 105651). Sanitizer instrumentation confuses GCC 12's flow analysis (false
# -Wuninitialized inside Eigen), so the test command leaves sanitizer builds showing warnings.
if(LIDARTAG_WERROR)
  target_compile_options(lidartag_warnings INTERFACE -Werror)
endif()

if(LIDARTAG_FUZZ)
  # libFuzzer's coverage instrumentation on all of the project's code, with ASan + UBSan; the fuzz
  # targets alone link the fuzzer's main (fuzz/CMakeLists.txt).
  if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    message(FATAL_ERROR "LIDARTAG_FUZZ needs clang (e.g. -DCMAKE_CXX_COMPILER=clang++-14)")
  endif()
  if(NOT LIDARTAG_SANITIZE STREQUAL "")
    message(FATAL_ERROR "LIDARTAG_FUZZ brings its own sanitizers: leave LIDARTAG_SANITIZE empty")
  endif()
  add_compile_options(-fsanitize=fuzzer-no-link,address,undefined,float-cast-overflow
                      -fno-sanitize-recover=all -fno-omit-frame-pointer)
  add_link_options(-fsanitize=address,undefined,float-cast-overflow)
endif()

if(LIDARTAG_SANITIZE STREQUAL "address")
  # float-cast-overflow is not part of `undefined`: it catches a NaN or huge float cast to an
  # integer (ring numbers, intensities, cell indices from corrupt input).
  add_compile_options(-fsanitize=address,undefined,float-cast-overflow -fno-omit-frame-pointer
                      -fno-sanitize-recover=all)
  add_link_options(-fsanitize=address,undefined,float-cast-overflow)
elseif(LIDARTAG_SANITIZE STREQUAL "thread")
  add_compile_options(-fsanitize=thread -fno-omit-frame-pointer)
  add_link_options(-fsanitize=thread)
elseif(NOT LIDARTAG_SANITIZE STREQUAL "")
  message(FATAL_ERROR "LIDARTAG_SANITIZE must be '', 'address' or 'thread'")
endif()

# lidartag_add_library(name SOURCES ... PUBLIC_LINK ... PRIVATE_LINK ...)
# Installed as lidartag::<name without "lidartag_"> (packaging/CMakeLists.txt): the include
# directory and the warnings are the build tree's only.
function(lidartag_add_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC_LINK;PRIVATE_LINK" ${ARGN})
  add_library(${name} STATIC ${ARG_SOURCES})
  target_include_directories(${name} PUBLIC $<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/include>
                                            $<INSTALL_INTERFACE:include>)
  target_link_libraries(${name} PUBLIC ${ARG_PUBLIC_LINK}
                        PRIVATE ${ARG_PRIVATE_LINK} $<BUILD_INTERFACE:lidartag_warnings>)
  string(REGEX REPLACE "^lidartag_" "" export_name ${name})
  set_target_properties(${name} PROPERTIES POSITION_INDEPENDENT_CODE ON EXPORT_NAME ${export_name})
endfunction()
