/* Compiled as strict C99: proves the public header is plain C. */
#include "photonlm/photonlm.h"

int plm_c99_check(void) {
  plm_bake_settings s;
  plm_light l;
  plm_bake_settings_default(&s);
  plm_light_default(&l, PLM_LIGHT_POINT);
  plm_ol_stats os;
  plm_lsystem_settings ls;
  plm_lsystem_stats lst;
  plm_lobe lobe;
  plm_lobe_default(&lobe, PLM_LOBE_GLASS);
  os.struct_size = sizeof os;
  os.resolution = 0;
  plm_lsystem_settings_default(&ls);
  lst.struct_size = sizeof lst;
  lst.resolution = 0;
  return (int)s.max_bounces + l.type + (int)os.resolution + (int)ls.ol_level + (int)lst.resolution + lobe.type;
}
