# CUDA likelihood backend (GMM_MCL_WITH_CUDA=ON): the kernels and the backend's host code as
# OBJECT libraries, which CMakeLists.txt compiles into gmm_mcl_core. Included before the core.
#
# Architectures: CMAKE_CUDA_ARCHITECTURES (CMakeLists.txt: default "75;80;90"; Jetson TX2: 62).
# C++14 for host and device code, nothing newer than CUDA 10.2 accepts.
if(CMAKE_VERSION VERSION_LESS 3.18)
  # Older CMake (JetPack 4 ships 3.10) ignores CMAKE_CUDA_ARCHITECTURES: pass -gencode flags.
  foreach(arch ${CMAKE_CUDA_ARCHITECTURES})
    string(APPEND CMAKE_CUDA_FLAGS " -gencode=arch=compute_${arch},code=sm_${arch}")
  endforeach()
endif()
enable_language(CUDA)
set(CMAKE_CUDA_STANDARD 14)
set(CMAKE_CUDA_STANDARD_REQUIRED ON)
set(CMAKE_CUDA_EXTENSIONS OFF)

if(CMAKE_VERSION VERSION_LESS 3.17)
  find_library(GMM_MCL_CUDART cudart HINTS ${CMAKE_CUDA_IMPLICIT_LINK_DIRECTORIES} REQUIRED)
  set(GMM_MCL_CUDART_TARGET ${GMM_MCL_CUDART})
  set(GMM_MCL_CUDA_INCLUDE ${CMAKE_CUDA_TOOLKIT_INCLUDE_DIRECTORIES})
else()
  find_package(CUDAToolkit REQUIRED)
  set(GMM_MCL_CUDART_TARGET CUDA::cudart)
  set(GMM_MCL_CUDA_INCLUDE ${CUDAToolkit_INCLUDE_DIRS})
endif()

# Kernels (nvcc) and the backend's host code (the C++ compiler, CUDA runtime API only).
add_library(gmm_mcl_cuda OBJECT
  # The likelihood backend: kernels, host code.
  src/backend/cuda/membership_kernel.cu
  src/backend/cuda/likelihood_kernel.cu
  src/backend/cuda/frame_kernel.cu
  src/backend/cuda/normal_equations_kernel.cu
  src/backend/cuda/cuda_backend.cpp
  src/backend/cuda/cuda_backend_launch.cpp
  src/backend/cuda/cuda_normal_equations.cpp
  # The device particle filter: kernels, host code.
  src/filter/cuda/filter_sampling_kernels.cu
  src/filter/cuda/filter_weight_kernels.cu
  src/filter/cuda/filter_resample_kernels.cu
  src/filter/cuda/cuda_particle_filter_impl.cpp
  src/filter/cuda/cuda_particle_filter.cpp
  src/filter/cuda/cuda_particle_filter_candidates.cpp
)
# The device filter's cub sorts and scans (src/filter/cuda/filter_sort.cu) in their own
# objects: CUDA 13's cub refuses C++14, so this one file (C++14 code) is compiled as C++17
# there; older toolkits (the TX2's CUDA 10.2) compile it as C++14 like every other file.
add_library(gmm_mcl_cuda_sort OBJECT src/filter/cuda/filter_sort.cu)
target_include_directories(gmm_mcl_cuda_sort PRIVATE
  ${CMAKE_CURRENT_SOURCE_DIR}/src/filter ${CMAKE_CURRENT_SOURCE_DIR}/include ${GMM_MCL_CUDA_INCLUDE})
target_compile_definitions(gmm_mcl_cuda_sort PRIVATE CCCL_IGNORE_DEPRECATED_CPP_DIALECT)
target_compile_options(gmm_mcl_cuda_sort PRIVATE -Xcompiler=-Wall)
if(CMAKE_CUDA_COMPILER_VERSION VERSION_GREATER_EQUAL 13)
  set_target_properties(gmm_mcl_cuda_sort PROPERTIES CUDA_STANDARD 17)
endif()
set_target_properties(gmm_mcl_cuda_sort PROPERTIES POSITION_INDEPENDENT_CODE ON)
# The sources include each other as "cuda/<file>": the backend's from src/backend (the shared
# device helpers: buffers, error checks), the device filter's from src/filter.
target_include_directories(gmm_mcl_cuda PRIVATE
  ${CMAKE_CURRENT_SOURCE_DIR}/src/backend ${CMAKE_CURRENT_SOURCE_DIR}/src/filter ${CMAKE_CURRENT_SOURCE_DIR}/include ${GMM_MCL_CUDA_INCLUDE})
# Eigen's headers, and the core's definitions: EIGEN_MAX_STATIC_ALIGN_BYTES=0 gives Eigen objects
# the same layout here as in the core. Not through target_link_libraries: CMake links OBJECT
# libraries from 3.12 on (JetPack 4 has 3.10).
target_include_directories(gmm_mcl_cuda SYSTEM PRIVATE
  $<TARGET_PROPERTY:${GMM_MCL_EIGEN_TARGET},INTERFACE_INCLUDE_DIRECTORIES>)
target_compile_definitions(gmm_mcl_cuda PRIVATE
  $<TARGET_PROPERTY:gmm_mcl_core,INTERFACE_COMPILE_DEFINITIONS>)
target_compile_options(gmm_mcl_cuda PRIVATE
  $<$<COMPILE_LANGUAGE:CUDA>:-Xcompiler=-Wall --expt-relaxed-constexpr -lineinfo>)
set_target_properties(gmm_mcl_cuda PROPERTIES POSITION_INDEPENDENT_CODE ON)
message(STATUS "gmm_mcl: CUDA backend for architectures ${CMAKE_CUDA_ARCHITECTURES}")
