# leveler_embed_text(FILE SYMBOL OUTPUT): a text file compiled into a program,
# so that values written once, in the file, need no second copy in C (the
# built-in plant config, the rig's defaults). OUTPUT (a .c file) gets
# `const char SYMBOL[]`, the file's bytes and a closing NUL; it is made at
# configure time, and again whenever FILE changes (a configure dependency).
function(leveler_embed_text file symbol output)
  set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS ${file})
  file(READ ${file} text_hex HEX)
  string(REGEX REPLACE "([0-9a-f][0-9a-f])" "0x\\1," text_bytes "${text_hex}")
  file(RELATIVE_PATH text_name ${PROJECT_SOURCE_DIR} ${file})
  file(CONFIGURE OUTPUT ${output}
       CONTENT "/* Made by cmake/embed_text.cmake from @text_name@: do not edit. */\nconst char @symbol@[] = {@text_bytes@ 0x00};\n"
       @ONLY)
endfunction()
