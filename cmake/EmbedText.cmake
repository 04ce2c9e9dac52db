# Embeds a text file in a C++ header as a string constant, at build time:
#   cmake -DINPUT=file.py -DOUTPUT=file.hpp -DNAME=identifier -P EmbedText.cmake
# The header defines `inline constexpr std::string_view mgcloth::embedded::NAME`. The file is rewritten only when
# its content changes, so that dependents are not rebuilt needlessly.
foreach(var INPUT OUTPUT NAME)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "EmbedText.cmake: -D${var}=... is required")
  endif()
endforeach()
file(READ "${INPUT}" text)
set(delimiter "mgcloth_embed")
string(FIND "${text}" ")${delimiter}\"" clash)
if(NOT clash EQUAL -1)
  message(FATAL_ERROR "EmbedText.cmake: ${INPUT} contains the raw-string delimiter )${delimiter}\"")
endif()
get_filename_component(source "${INPUT}" NAME)
set(content "// Generated from ${source} by cmake/EmbedText.cmake; edit the source, not this file.
#pragma once
#include <string_view>

namespace mgcloth::embedded {
inline constexpr std::string_view ${NAME} = R\"${delimiter}(${text})${delimiter}\";
}  // namespace mgcloth::embedded
")
file(WRITE "${OUTPUT}.tmp" "${content}")
file(COPY_FILE "${OUTPUT}.tmp" "${OUTPUT}" ONLY_IF_DIFFERENT)
file(REMOVE "${OUTPUT}.tmp")
