/* Compiled as strict C99: proves the public header is plain C. */
#include "photonlm/photonlm.h"

int plm_c99_check(void) {
  plm_bake_settings s;
  plm_light l;
  plm_bake_settings_default(&s);
  plm_light_default(&l, PLM_LIGHT_POINT);
  plm_ol_stats os;
  os.resolution = 0;
  return (int)s.max_bounces + l.type + (int)os.resolution;
}
