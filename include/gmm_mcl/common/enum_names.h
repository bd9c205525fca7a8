// Enumerations read from their names (parameters, message encodings): a table of name and value.
#pragma once

#include <cstddef>
#include <string>

namespace gmm_mcl {

template <class Enum>
struct EnumName {
  const char* name;
  Enum value;
};

// Sets *out to the value of the table's entry named `name`; false (*out untouched) when none is.
template <class Enum, std::size_t N>
bool parseEnumName(const std::string& name, const EnumName<Enum> (&table)[N], Enum* out) {
  for (const EnumName<Enum>& e : table) {
    if (name == e.name) {
      *out = e.value;
      return true;
    }
  }
  return false;
}

// The name of the table's first entry with value `value`; "" when none has it.
template <class Enum, std::size_t N>
const char* enumNameOf(Enum value, const EnumName<Enum> (&table)[N]) {
  for (const EnumName<Enum>& e : table) {
    if (e.value == value) return e.name;
  }
  return "";
}

}  // namespace gmm_mcl
